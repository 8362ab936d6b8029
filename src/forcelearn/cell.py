"""A cell: a robot, a force sensor and the force filter, with the force limit on every reading.

The cell is what the trainer's tasks move and read. It knows the devices only
through the :class:`~forcelearn.devices.Robot` and
:class:`~forcelearn.devices.ForceSensor` protocols, so an emulated cell and a
real one are the same object with other drivers inside.

Safety, always on:

* every motion goes through the robot driver, which refuses a step above its
  limit or a target outside its workspace before any byte is sent, and every
  move is waited for: the cell reads the force only once the robot reports in
  position and has settled (``NotInPosition`` after ``move_timeout_s``, robot
  stopped);
* every reading goes through the sensor driver, whose watchdog raises
  ``SensorStale`` when samples stop;
* :meth:`Cell.measure_force_n` raises :class:`~forcelearn.errors.ForceLimitExceeded`
  when the filtered normal force, or the force magnitude of any single sample,
  passes ``max_force_n``, or a sample saturated the sensor;
* any device error stops the robot (best effort) before it propagates.

With a :attr:`Cell.recorder` set, every waited move, every burst of samples and
every tare is also handed to it as a :mod:`forcelearn.records` value (the run
directory's ``records.mcap``); without one nothing is computed.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import ParamSpec, TypeVar

import numpy as np

from forcelearn.calibration.model import Calibration
from forcelearn.calibration.tool_check import MIN_TURN_DEG, check_free_space, turn_deg
from forcelearn.devices import (
    BatchForceSensor,
    ForceSensor,
    InPositionWait,
    Pose,
    RebootableSensor,
    Robot,
    WrenchSample,
)
from forcelearn.errors import (
    ConfigError,
    ForcelearnError,
    ForceLimitExceeded,
    InvalidTarget,
    ToolMismatch,
)
from forcelearn.filtering import ForceFilter, MoveAwareForceFilter
from forcelearn.filtering.burst_record import burst_record
from forcelearn.press_guard import (
    DRIFT_CHECKS,
    MIN_STEP_MM,
    NOISE_SIGMAS,
    REFRESH_GAIN_N,
    REFRESH_SHARE,
    DriftCheck,
    PressGuard,
    check_samples,
    drift_allowance_n,
    drift_rate_bound_n_per_s,
    unseen_drift_n,
)
from forcelearn.records import CellRecorder, MoveRecord, TareRecord

log = logging.getLogger(__name__)

MAX_STEPS_PER_MOVE = 10_000
"""Most steps one move is cut into (a tiny step limit would otherwise never arrive)."""

SYNC_WINDOW = 16
"""Samples requested at once from a batch sensor (a real adapter's transmit queue is short)."""

WrenchCompensation = Callable[[np.ndarray, Pose], np.ndarray]
"""Maps a measured wrench (sensor frame, N and N·m) and the pose to a compensated one."""

_P = ParamSpec("_P")
_R = TypeVar("_R")


class Cell:
    """A robot + force sensor + force filter, guarded by a force limit.

    Args:
        robot: the robot driver.
        sensor: the force/torque sensor driver.
        force_filter: the Kalman filter of the normal force (its config picks
            the axis and sign of the normal force); a move-aware filter is
            told of every move the cell makes.
        max_force_n: force (N) above which motion stops and the trial fails: the
            filtered normal force, or the force magnitude of any sample.
        samples_per_step: sensor samples read (and filtered) after each move.
        compensation: optional wrench compensation hook (a calibration brings its own).
        move_timeout_s: longest wait (robot's time) for a move to be in position.
        settle_s: dwell in position before the force is measured, s.
        calibration: the sensor's calibration (``forcelearn calibrate``), valid for the
            zero the sensor has now: the filter takes R from its noise on the filter's
            axis, every sample loses its bias and the tool's weight, and every
            :meth:`tare` re-derives its bias for the pose it zeroed at.
    """

    def __init__(
        self,
        robot: Robot,
        sensor: ForceSensor,
        force_filter: ForceFilter | MoveAwareForceFilter,
        max_force_n: float,
        samples_per_step: int = 5,
        compensation: WrenchCompensation | None = None,
        move_timeout_s: float = 10.0,
        settle_s: float = 0.05,
        calibration: Calibration | None = None,
    ):
        if not (math.isfinite(move_timeout_s) and move_timeout_s > 0):
            raise ConfigError(f"move_timeout_s must be a finite number > 0, got {move_timeout_s!r}")
        if not (math.isfinite(settle_s) and settle_s >= 0):
            raise ConfigError(f"settle_s must be a finite number >= 0, got {settle_s!r}")
        if not (math.isfinite(max_force_n) and max_force_n > 0):
            raise ConfigError(f"max_force_n must be a finite number > 0, got {max_force_n!r}")
        if samples_per_step < 1:
            raise ConfigError(f"samples_per_step must be >= 1, got {samples_per_step}")
        self.robot = robot
        self.sensor = sensor
        self.force_filter = force_filter
        self.max_force_n = float(max_force_n)
        self.samples_per_step = int(samples_per_step)
        self.calibration = calibration
        """The calibration in force (re-derived at every tare), or None."""
        self.compensation = compensation
        if calibration is not None:
            if compensation is not None:
                raise ConfigError("give a Cell a calibration or a compensation, not both")
            force_filter.set_measurement_variance(
                calibration.noise_variance(force_filter.config.axis)
            )
            self.compensation = calibration.compensation
        self.move_timeout_s = float(move_timeout_s)
        self.settle_s = float(settle_s)
        self.time_s = 0.0
        """The robot's clock (s) at the end of the last wait: the cell's time."""
        self._pose: Pose | None = None
        self.on_tare: Callable[[Pose], None] | None = None
        """Called with the pose after every :meth:`tare` (after the calibration followed it)."""
        self.tares = 0
        """Tares done."""
        self.tares_refused = 0
        """Tares refused because the free-space reading was too large."""
        self.recorder: CellRecorder | None = None
        """Receives every move, burst and tare as a record (None: nothing is recorded)."""
        self.stage: tuple[str, int] = ("move", 0)
        """What the present moves are for, (kind, index) as in
        :class:`~forcelearn.records.StepRecord`: set by the task, read by recorders."""
        self.reading_check: Callable[[tuple[str, int], Pose | None, float], None] | None = None
        """Called with (stage, pose commanded, normal force N) after every burst of more than
        one sample; may
        raise a :class:`~forcelearn.errors.SensorError` (the robot is then stopped), e.g.
        :class:`~forcelearn.tasks.bias_watch.BiasWatch`. None: nothing checked."""
        self.zero_residual = np.zeros(6)
        """The zero's correction in software (the last zero check's mean wrench), N and N*m."""
        self.zero_std_n: float | None = None
        """The zero's own standard deviation on the normal axis, N (None: the sensor's zero)."""
        self.zero_time_s = 0.0
        """The cell time of the last zero, s."""
        self.burst_frozen = False
        """The last burst's samples (three or more) all read the very same wrench: a live
        sensor's noise never repeats exactly, so the sensor or its link repeats one frame."""
        self.drift_rate_n_per_s = 0.0
        """The fastest drift of the bias the recent zero checks cannot rule out, N/s
        (:func:`~forcelearn.press_guard.drift_rate_bound_n_per_s`; the press guard keeps
        headroom for it)."""
        self.drift_checks: list[DriftCheck] = []
        """The recent zero checks' drift measurements (the last :data:`DRIFT_CHECKS`)."""
        self._last_mean_wrench = np.zeros(6)
        self.press_guard: PressGuard | None = None
        """Bounds each guarded move's press-in by the known stiffness (None: no bound)."""
        self.refresh_zero: Callable[[], None] | None = None
        """Retracts to free space, checks the zero there and presses back to where the tool
        was (set by a run that checks its zero, ``[task] zero_check``; may raise
        :class:`~forcelearn.errors.ZeroMoved`). With it the press guard keeps headroom for a
        drift no check has seen (:meth:`unseen_drift_n`) when it presses on from contact, and
        a guarded move cut there calls it first when that headroom passes the measured one by
        :data:`~forcelearn.press_guard.REFRESH_GAIN_N` and by
        :data:`~forcelearn.press_guard.REFRESH_SHARE` of the force left to the limit.
        None: no zero is checked between presses, so that headroom would only grow: the
        measured drift alone is kept."""
        self.zero_refreshes = 0
        """Presses made again from a fresh zero (:attr:`refresh_zero`)."""
        self._refreshing = False

    @property
    def pose(self) -> Pose:
        """The last pose commanded or read (reads the robot if none yet)."""
        if self._pose is None:
            self._pose = self._guarded(self.robot.read_pose)
        return self._pose

    @property
    def known_pose(self) -> Pose | None:
        """The last pose commanded or read, without asking the robot (None: none yet)."""
        return self._pose

    def read_pose(self) -> Pose:
        """Read the robot's pose now."""
        self._pose = self._guarded(self.robot.read_pose)
        return self._pose

    def sync(self) -> Pose:
        """Take the robot's commanded target as the cell's pose and read its clock.

        Called at the start of every trial, so a run resumed on a cell that
        was restored elsewhere starts from what the controller holds.
        """
        self._pose = self._guarded(self.robot.read_target)
        self.time_s = self._guarded(self.robot.wait_in_position, self.move_timeout_s, 0.0)
        return self._pose

    def move_to(self, pose: Pose, settle: bool = True) -> None:
        """Move to ``pose`` and wait until the robot is there (and settled, if ``settle``).

        Driver limits apply; stops the robot on any device error.
        """
        start_s = self.time_s
        self._pose = None
        self._guarded(self.robot.move_to, pose)
        self._pose = pose
        on_move = getattr(self.force_filter, "on_move", None)
        if on_move is not None:
            on_move()  # the force may change by anything: the filter starts over its prior
        try:
            self.time_s = self._guarded(
                self.robot.wait_in_position, self.move_timeout_s, self.settle_s if settle else 0.0
            )
        except ForcelearnError:
            self._pose = None  # not reached: where the robot is must be read again
            raise
        if self.recorder is not None:
            self.recorder.on_move(self._move_record(pose, start_s))

    def _move_record(self, pose: Pose, start_s: float) -> MoveRecord:
        """The record of a move just waited for (times on the robot's clock, s)."""
        wait = getattr(self.robot, "last_wait", None)
        in_position_s, reached = self.time_s, (math.nan,) * 3
        if isinstance(wait, InPositionWait):
            in_position_s = wait.in_position_s
            if wait.reached is not None:
                reached = _xyz(wait.reached)
        return MoveRecord(_xyz(pose), reached, start_s, in_position_s, self.time_s)

    def move_in_steps(self, target: Pose, max_step_mm: float, guard_force: bool = False) -> int:
        """Move to ``target`` in straight steps of at most ``max_step_mm``; returns the count.

        Steps are planned 1 % under the limit, so rounding never asks the driver
        for a step it must refuse. Each step is waited for; only the last one
        settles. With ``guard_force`` (moves that may meet contact) one sample
        is read after every intermediate step, so the force limit stops the
        robot on the way, not only at the target, and with a :attr:`press_guard`
        a step whose predicted force passes the limit is cut where the prediction
        allows, and the force read there (:mod:`forcelearn.press_guard`); where it allows no
        further step the move is refused (:class:`ForceLimitExceeded`, the robot stopped).
        """
        return self._stepped(target, max_step_mm, guard_force, None)[0]

    def press_in_steps(self, target: Pose, max_step_mm: float, stop_at_n: float) -> bool:
        """A guarded :meth:`move_in_steps` that aims as deep as ``stop_at_n`` (N) lets it.

        ``stop_at_n`` is under the safety limit (the surface probe's own limit). Where the
        press guard cuts a step and its last reading has passed ``stop_at_n``, or it allows no
        further step, the move ends there, at rest, instead of being refused. Returns True
        when it ended short of ``target`` (:attr:`pose` says where).
        """
        return self._stepped(target, max_step_mm, True, stop_at_n)[1]

    def _stepped(self, target: Pose, max_step_mm: float, guard_force: bool,
                 stop_at_n: float | None) -> tuple[int, bool]:
        """The moves made and whether the press ended short of ``target``.

        :meth:`move_in_steps` (``stop_at_n`` None) or :meth:`press_in_steps`.
        """
        start = self.pose
        distance = float(np.linalg.norm(target.position_mm - start.position_mm))
        if distance == 0.0 and target.quaternion == start.quaternion:
            return 0, False  # already there: send nothing
        count = max(1, math.ceil(distance / (0.99 * max_step_mm)))
        if count > MAX_STEPS_PER_MOVE:
            raise InvalidTarget(
                f"a move of {distance:.1f} mm in steps of at most {max_step_mm:g} mm "
                f"(safety.max_step_mm) would take {count} steps, more than "
                f"{MAX_STEPS_PER_MOVE}: raise safety.max_step_mm; nothing was sent"
            )
        guard = self.press_guard if guard_force else None
        moves, i, refreshed = 0, 1, False
        while i <= count:
            step = _towards(start, target, i / count)
            if guard is not None:
                guard.drift_n = self.drift_allowance_n(in_contact=guard.in_contact)
            if guard is not None and (share := guard.reach(self.pose.position_mm,
                                                           step.position_mm)) < 1.0:
                if not refreshed and self._refresh_pays(guard):
                    refreshed = True  # once per move: the drift since is then bounded
                    self._refresh()
                    continue
                if stop_at_n is not None and _pressed_enough(guard, stop_at_n, share * float(
                        np.linalg.norm(step.position_mm - self.pose.position_mm))):
                    log.info("the press ends %.2f mm short of its target at %.3g N (it aimed at "
                             "most %.3g N)", float(np.linalg.norm(
                                 target.position_mm - self.pose.position_mm)),
                             guard.last[1] if guard.last else math.nan, stop_at_n)
                    return moves, True
                self._guarded_part(guard, step, share)
                moves += 1
                if moves > MAX_STEPS_PER_MOVE:
                    raise InvalidTarget(f"a guarded move took over {MAX_STEPS_PER_MOVE} steps")
                continue
            self.move_to(step, settle=i == count)
            moves += 1
            if guard_force and i < count:
                self.measure_force_n(1)
            i += 1
        return moves, False

    def _refresh_pays(self, guard: PressGuard) -> bool:
        """A cut from contact whose unseen-drift headroom is worth a fresh zero."""
        if self.refresh_zero is None or self._refreshing or not guard.in_contact:
            return False
        measured = self.drift_allowance_n()
        extra = self.unseen_drift_n() - measured
        return extra > max(REFRESH_GAIN_N, REFRESH_SHARE * guard.force_left_n(measured))

    def _refresh(self) -> None:
        """Retract, check the zero in free space and press back (:attr:`refresh_zero`)."""
        assert self.refresh_zero is not None
        log.info("the zero is %.1f s old at a press near the limit: retracting to check it",
                 self.time_s - self.zero_time_s)
        self._refreshing = True  # none inside its own moves
        try:
            self.refresh_zero()
        finally:
            self._refreshing = False
        self.zero_refreshes += 1

    def _guarded_part(self, guard: PressGuard, step: Pose, share: float) -> None:
        """Move ``share`` of the way to ``step`` (as far as the press guard allows) and read."""
        here = self.pose
        guard.cuts += 1
        if share * float(np.linalg.norm(step.position_mm - here.position_mm)) < MIN_STEP_MM:
            self.stop()
            raise ForceLimitExceeded(
                f"the next move would press past safety.max_force_n = {self.max_force_n} N "
                f"(last reading {guard.last[1] if guard.last else math.nan:.2f} N, stiffness "
                f"{guard.stiffness_n_per_mm:.1f} N/mm); the robot was stopped"
            )
        self.move_to(_towards(here, step, share), settle=False)
        self.measure_force_n(1)

    def reset_filter(self) -> None:
        """Forget the filter's track (at the start of a trial)."""
        self.force_filter.reset()

    def measure_force_n(self, samples: int | None = None) -> float:
        """Read ``samples`` sensor samples through the filter; return the normal force (N).

        Raises:
            ForceLimitExceeded: a sample or the filtered force passed ``max_force_n``
                (the robot has been stopped).
            SensorStale: no sample arrived in the watchdog time (robot stopped).
        """
        count = samples or self.samples_per_step
        if isinstance(self.sensor, BatchForceSensor):  # windows of SYNCs in flight
            batch = self._guarded(self.sensor.read_many, count, min(count, SYNC_WINDOW))
        else:
            batch = [self._guarded(self.sensor.read) for _ in range(count)]
        self.burst_frozen = len(batch) > 2 and all(
            np.array_equal(batch[0].wrench, sample.wrench) for sample in batch[1:])
        compensated, wrenches = self._compensated_burst(batch)  # (n, 6): the mean's, the guard's
        self._last_mean_wrench = np.mean(wrenches, axis=0)
        force = math.nan
        if self.press_guard is not None and self._pose is not None:
            normal = self.force_filter.config.normal_force(wrenches)
            # where the arm is, not where it was sent: an EGM arm ends its in-position zone
            # short of a press, and a reading booked deeper than it was taken buys depth
            self._guarded(self.press_guard.note, self.reached_pose().position_mm,
                          float(np.max(normal)))
        try:
            try:
                check_samples(compensated, self.max_force_n, self.force_filter.config)
            except ForceLimitExceeded:
                self.stop()
                raise
            on_burst = getattr(self.force_filter, "on_burst", None)
            if on_burst is not None:
                on_burst(compensated)
            else:
                for sample in compensated:
                    self.force_filter.on_sample(sample)
            force = self.force_filter.force_n
        finally:  # a burst that passed the limit is recorded too (filtered: NaN)
            if self.recorder is not None:
                self.recorder.on_burst(burst_record(self.force_filter.config, compensated, force,
                                                 self.time_s))
        if abs(force) > self.max_force_n:
            self.stop()
            raise ForceLimitExceeded(
                f"filtered normal force {force:.2f} N passed safety.max_force_n = "
                f"{self.max_force_n} N; the robot was stopped"
            )
        if (samples is None or samples > 1) and self.reading_check is not None:
            self._guarded(self.reading_check, self.stage, self._pose, force)
        return force

    def tare(self, max_reading_n: float) -> bool:
        """Zero the sensor here (the tool at rest in free space); True if it was zeroed.

        The normal force is read first. If it is more than ``max_reading_n`` (N)
        from zero, something touches the tool or the sensor jumped; zeroing then
        would hide a real force, so it is refused (a warning, False).
        """
        force = self.measure_force_n()
        accepted = abs(force) <= max_reading_n
        if self.recorder is not None:  # the trial is the recorder's to fill in
            here = _xyz(self._pose) if self._pose is not None else (math.nan,) * 3
            self.recorder.on_tare(TareRecord(-1, self.time_s, here, force, accepted))
        if not accepted:
            self.tares_refused += 1
            log.warning(
                "not zeroing the sensor: it reads %.2f N in free space, more than "
                "task.tare_max_reading_n = %g N (is the tool touching something at the "
                "retract pose, task.retract_y_mm?)", force, max_reading_n,
            )
            return False
        self.check_tool_fit()  # turned since the last zero: does the calibrated tool still fit?
        self._take_zero()
        return True

    def check_zero(self, bound_n: Callable[[float], float]) -> tuple[float, float]:
        """In free space: read a burst; zero on its mean if within the bound; (reading, bound) N.

        The zero check at a trial's end: the tool at rest in free space must read
        the zero the trial ran with. ``bound_n`` maps the burst's own standard
        deviation (the filter's, N) to the bound. Within it, the burst's mean wrench
        becomes the zero (in software: a zero of a whole burst, not of the sensor's
        own few samples); beyond it nothing is zeroed (the caller voids what was read
        since the last zero, :class:`~forcelearn.errors.ZeroMoved`). Recorded as a
        tare, accepted or not; the reading check is not consulted (this is the check).
        """
        force = self._read_unjudged()
        std = getattr(self.force_filter, "force_std_n", math.nan)
        if not math.isfinite(std):
            std = math.sqrt(self.force_filter.measurement_variance_n2 / self.samples_per_step)
        bound = bound_n(std)
        accepted = abs(force) <= bound
        zero_std = (math.sqrt(self.force_filter.measurement_variance_n2)
                    if self.zero_std_n is None else self.zero_std_n)
        noise = NOISE_SIGMAS * math.hypot(std, zero_std)
        elapsed = self.time_s - self.zero_time_s
        if elapsed > 0.0:  # what the zero moved by, and what the noise may hide, over its time
            check = DriftCheck(force, noise, elapsed, self.zero_time_s)
            if self.drift_checks and self.drift_checks[-1].zero_time_s == self.zero_time_s:
                self.drift_checks[-1] = check  # read again over the same time: the latest
            else:
                self.drift_checks = [*self.drift_checks, check][-DRIFT_CHECKS:]
            self.drift_rate_n_per_s = drift_rate_bound_n_per_s(self.drift_checks)
        if self.recorder is not None:
            here = _xyz(self._pose) if self._pose is not None else (math.nan,) * 3
            self.recorder.on_tare(TareRecord(-1, self.time_s, here, force, accepted))
        if accepted:
            self.zero_residual = self.zero_residual + self._last_mean_wrench
            self.zero_std_n, self.zero_time_s = std, self.time_s
            self._take_zero(hardware=False)
        return force, bound

    def drift_allowance_n(self, in_contact: bool = False) -> float:
        """What the bias may have drifted since the zero, N (the press guard's headroom).

        ``in_contact``: from a reading in contact, at least :meth:`unseen_drift_n` where the
        zero is checked between presses (:attr:`refresh_zero`; a drift in contact hides
        force, from free space the prediction starts from no force).
        """
        measured = drift_allowance_n(self.drift_rate_n_per_s,
                                     self.force_filter.config.bias_drift_n_per_sqrt_s,
                                     self.time_s - self.zero_time_s)
        if in_contact and self.refresh_zero is not None:
            return max(measured, self.unseen_drift_n())
        return measured

    def unseen_drift_n(self) -> float:
        """What a drift started since the last zero, which no check saw, may hide, N."""
        return unseen_drift_n(self.force_filter.config.bias_drift_max_n_per_s,
                              self.time_s - self.zero_time_s)

    def _take_zero(self, hardware: bool = True) -> None:
        """Zero the sensor here (else the caller zeroed in software); the calibration follows."""
        if hardware:
            self._guarded(self.sensor.zero_offsets)
            self.zero_residual, self.zero_std_n, self.zero_time_s = np.zeros(6), None, self.time_s
        self.tares += 1
        if self.press_guard is not None:  # free space reads 0 from now on
            self.press_guard.note(self.reached_pose().position_mm, 0.0)
            if hardware:  # a new zero (a tare, after a fault): no press to compare with yet
                self.press_guard.referenced = False
        if hardware:  # a software zero leaves the sensor's own zero and its calibrated bias
            self.zero_taken_at(self.pose.quaternion)
        if self.on_tare is not None:
            self.on_tare(self.pose)

    def zero_taken_at(self, quaternion: tuple[float, float, float, float]) -> None:
        """The sensor's zero holds the tool's weight at ``quaternion``: the calibration follows.

        After every zero; and when a resumed run restored an emulated sensor with the zero
        its last session took (at another orientation than this session's first).
        """
        if self.calibration is not None:
            self.calibration = self.calibration.rezeroed(quaternion)
            self.compensation = self.calibration.compensation

    def zero_in_free_space(self) -> float:
        """Zero the sensor after a fault, the tool retracted to free space; return the reading (N).

        Unlike :meth:`tare` no bound on the reading: after a reboot the sensor
        reads its raw bias, which is what the zero is for. The caller must have
        moved the tool clear of every surface
        (:func:`forcelearn.tasks.recovery.retract_and_retare`). A sensor that
        rebooted (:class:`~forcelearn.devices.RebootableSensor`) is started
        again first; one burst is read (the sensor must answer; the force limit
        and saturation checks apply), the zero taken and recorded, the
        calibration's bias re-derived and the filter reset.
        """
        reinitialise = getattr(self.sensor, "reinitialise", None)
        if isinstance(self.sensor, RebootableSensor) and reinitialise is not None:
            self._guarded(reinitialise)
        self.reset_filter()
        force = self._read_unjudged()
        if self.recorder is not None:
            here = _xyz(self._pose) if self._pose is not None else (math.nan,) * 3
            self.recorder.on_tare(TareRecord(-1, self.time_s, here, force, True))
        self._take_zero()
        self.reset_filter()
        return force

    def _read_unjudged(self) -> float:
        """A burst no reading check judges (a zero's: it reads the bias it is about to take)."""
        check, guard, self.reading_check, self.press_guard = (
            self.reading_check, self.press_guard, None, None)
        try:
            return self.measure_force_n()
        finally:
            self.reading_check, self.press_guard = check, guard

    def stop(self) -> None:
        """Stop the robot now (best effort: a failing link is logged, not raised)."""
        try:
            self.robot.stop()
        except ForcelearnError as exc:
            log.error("could not stop the robot: %s", exc)

    # ---- compensation at the orientation reached (docs/calibration.md) ---------------------
    def reached_pose(self) -> Pose:
        """The pose the robot reported at the end of its last wait, else the one commanded.

        A link that reports no pose with its wait (the computer link) leaves the
        commanded pose, which the controller holds within its in-position zone.
        """
        wait = getattr(self.robot, "last_wait", None)
        if isinstance(wait, InPositionWait) and wait.reached is not None:
            return wait.reached
        return self.pose

    def _compensated(self, sample: WrenchSample) -> WrenchSample:
        wrench = (sample.wrench if self.compensation is None
                  else self.compensation(sample.wrench, self.reached_pose()))
        if any(self.zero_residual.tolist()):  # .any() of six numbers, without a ufunc (hot)
            wrench = np.asarray(wrench, dtype=float) - self.zero_residual
        elif self.compensation is None:
            return sample
        return sample.with_wrench(wrench)  # keeps its time, counter, flags

    def _compensated_burst(
        self, batch: list[WrenchSample]
    ) -> tuple[list[WrenchSample], np.ndarray]:
        """:meth:`_compensated` of each sample, and their wrenches as one (n, 6) array.

        The residual's test is made once per burst, and a residual is taken off the
        burst's array at once (the same subtraction per element); each compensated
        sample's wrench is then its row.
        """
        if self.compensation is not None:
            compensated = [self._compensated(sample) for sample in batch]
            return compensated, np.array([s.wrench for s in compensated])
        residual = self.zero_residual
        if not any(residual.tolist()):
            return list(batch), np.array([s.wrench for s in batch])
        wrenches = np.array([s.wrench for s in batch], dtype=float) - residual
        samples = [sample.with_wrench(wrench)
                   for sample, wrench in zip(batch, wrenches, strict=True)]
        return samples, wrenches

    def check_tool_fit(self, samples: int | None = None) -> bool:
        """In free space: raise ToolMismatch if the calibrated tool no longer fits here.

        Only at an orientation turned from the last zero's (else nothing shows;
        False, nothing read): reads a burst, compensated at the orientation
        reached, against 3 sigma of the calibration's noise. Call it whenever the
        tool is in free space after a turn; :meth:`tare` does before zeroing.
        """
        cal = self.calibration
        if cal is None:
            return False
        here = self.reached_pose().quaternion
        if turn_deg(here, cal.zero_quaternion) < MIN_TURN_DEG:
            return False
        count = samples or self.samples_per_step
        batch = [self._compensated(self._guarded(self.sensor.read)) for _ in range(count)]
        mean = np.mean([s.wrench for s in batch], axis=0)
        try:
            return check_free_space(cal, mean, here, cal.zero_quaternion)
        except ToolMismatch:
            self.stop()
            raise

    def _guarded(self, call: Callable[_P, _R], *args: _P.args, **kwargs: _P.kwargs) -> _R:
        try:
            return call(*args, **kwargs)
        except ForcelearnError:
            self.stop()
            raise


def _pressed_enough(guard: PressGuard, stop_at_n: float, allowed_mm: float) -> bool:
    """Whether a press cut by ``guard`` (``allowed_mm`` further allowed) ends where it is."""
    return allowed_mm < MIN_STEP_MM or (guard.last is not None and guard.last[1] > stop_at_n)


def _towards(start: Pose, target: Pose, f: float) -> Pose:
    """The pose ``f`` of the straight way from ``start`` to ``target`` (target's orientation)."""
    return Pose(start.x_mm + f * (target.x_mm - start.x_mm),
                start.y_mm + f * (target.y_mm - start.y_mm),
                start.z_mm + f * (target.z_mm - start.z_mm), target.quaternion)


def _xyz(pose: Pose) -> tuple[float, float, float]:
    """A pose's position (x, y, z), mm, as plain floats."""
    return (float(pose.x_mm), float(pose.y_mm), float(pose.z_mm))
