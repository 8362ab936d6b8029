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

import dataclasses
import logging
import math
from collections.abc import Callable
from typing import ParamSpec, TypeVar

import numpy as np

from forcelearn.calibration.model import Calibration
from forcelearn.calibration.tool_check import MIN_TURN_DEG, check_free_space, turn_deg
from forcelearn.devices import (
    AXES,
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
from forcelearn.records import BurstRecord, CellRecorder, MoveRecord, TareRecord

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
        robot on the way, not only at the target.
        """
        start = self.pose
        distance = float(np.linalg.norm(target.position_mm - start.position_mm))
        if distance == 0.0 and target.quaternion == start.quaternion:
            return 0  # already there: send nothing
        count = max(1, math.ceil(distance / (0.99 * max_step_mm)))
        if count > MAX_STEPS_PER_MOVE:
            raise InvalidTarget(
                f"a move of {distance:.1f} mm in steps of at most {max_step_mm:g} mm "
                f"(safety.max_step_mm) would take {count} steps, more than "
                f"{MAX_STEPS_PER_MOVE}: raise safety.max_step_mm; nothing was sent"
            )
        for i in range(1, count + 1):
            f = i / count
            self.move_to(
                Pose(
                    start.x_mm + f * (target.x_mm - start.x_mm),
                    start.y_mm + f * (target.y_mm - start.y_mm),
                    start.z_mm + f * (target.z_mm - start.z_mm),
                    target.quaternion,
                ),
                settle=i == count,
            )
            if guard_force and i < count:
                self.measure_force_n(1)
        return count

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
        compensated = [self._compensated(raw) for raw in batch]
        force = math.nan
        try:
            self._check_samples(compensated)
            on_burst = getattr(self.force_filter, "on_burst", None)
            if on_burst is not None:
                on_burst(compensated)
            else:
                for sample in compensated:
                    self.force_filter.on_sample(sample)
            force = self.force_filter.force_n
        finally:  # a burst that passed the limit is recorded too (filtered: NaN)
            if self.recorder is not None:
                self.recorder.on_burst(self._burst_record(compensated, force))
        if abs(force) > self.max_force_n:
            self.stop()
            raise ForceLimitExceeded(
                f"filtered normal force {force:.2f} N passed safety.max_force_n = "
                f"{self.max_force_n} N; the robot was stopped"
            )
        if (samples is None or samples > 1) and self.reading_check is not None:
            self._guarded(self.reading_check, self.stage, self._pose, force)
        return force

    def _burst_record(self, samples: list[WrenchSample], filtered_n: float) -> BurstRecord:
        """Statistics of a burst's compensated normal force (N) and its time span (s).

        The burst starts at the cell time of the last wait (the first sample is
        requested then); its span is the sensor's own time between its samples
        when the sensor tells it, else the filter's sample period per sample.
        """
        config = self.force_filter.config
        wrenches = np.array([s.wrench for s in samples], dtype=float)
        normal = config.normal_force(wrenches)
        gaps = [s.sensor_dt_s for s in samples[1:]]
        span = (
            float(sum(g for g in gaps if g is not None)) if all(g is not None for g in gaps)
            else (len(samples) - 1) * config.sample_period_s
        )
        mean = wrenches.mean(axis=0)
        return BurstRecord(
            mean_n=float(normal.mean()),
            std_n=float(normal.std()),
            first_n=float(normal[0]),
            last_n=float(normal[-1]),
            count=len(samples),
            start_s=self.time_s,
            span_s=span,
            filtered_n=float(filtered_n),
            wrench_mean=(float(mean[0]), float(mean[1]), float(mean[2]),
                         float(mean[3]), float(mean[4]), float(mean[5])),
        )

    def _check_samples(self, samples: list[WrenchSample]) -> None:
        """Stop on a sample whose force magnitude passes the limit, or that saturated.

        The limit is on |(Fx, Fy, Fz)|, not on the signed normal force alone: a
        wrong ``[filter] axis`` or ``sign`` must not let the robot press on unseen.
        A saturated axis means the sensor cannot tell the force, so it stops too.
        """
        forces = np.array([s.wrench[:3] for s in samples], dtype=float)
        magnitudes = np.sqrt(np.einsum("ij,ij->i", forces, forces))
        worst = int(np.argmax(magnitudes))
        magnitude = float(magnitudes[worst])
        any_saturated = any(any(s.saturated) for s in samples)
        if magnitude <= self.max_force_n and not any_saturated:
            return
        self.stop()
        config = self.force_filter.config
        saturated = [AXES[i] for i in range(6) if any(s.saturated[i] for s in samples)]
        if saturated:
            raise ForceLimitExceeded(
                f"the sensor is near its full scale on {', '.join(saturated)} (force "
                f"{magnitude:.2f} N): the force is not known; the robot was stopped"
            )
        normal = float(config.normal_force(samples[worst].wrench))
        hint = (
            f"; only {normal:.2f} N of it is along the normal ([filter] axis = {config.axis}, "
            f"sign = {config.sign:g}): check that axis and sign"
            if normal < 0.5 * magnitude else ""
        )
        raise ForceLimitExceeded(
            f"contact force {magnitude:.2f} N passed safety.max_force_n = "
            f"{self.max_force_n} N{hint}; the robot was stopped"
        )

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

    def check_zero(self, max_change_n: float) -> float:
        """In free space: read a burst; zero here if it is within ``max_change_n`` (N) of 0.

        The zero check at a trial's end: the tool at rest in free space must read
        the zero the trial ran with. Returns the reading (N); a reading beyond
        the bound zeroes nothing (the caller voids what was read since the last
        zero, :class:`~forcelearn.errors.ZeroMoved`). Recorded as a tare, accepted
        or not; the reading check is not consulted (this is the check).
        """
        check, self.reading_check = self.reading_check, None
        try:
            force = self.measure_force_n()
        finally:
            self.reading_check = check
        accepted = abs(force) <= max_change_n
        if self.recorder is not None:
            here = _xyz(self._pose) if self._pose is not None else (math.nan,) * 3
            self.recorder.on_tare(TareRecord(-1, self.time_s, here, force, accepted))
        if accepted:
            self._take_zero()
        return force

    def _take_zero(self) -> None:
        """Zero the sensor here and make the calibration follow (the tool's weight at this pose)."""
        self._guarded(self.sensor.zero_offsets)
        self.tares += 1
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
        force = self.measure_force_n()
        if self.recorder is not None:
            here = _xyz(self._pose) if self._pose is not None else (math.nan,) * 3
            self.recorder.on_tare(TareRecord(-1, self.time_s, here, force, True))
        self._take_zero()
        self.reset_filter()
        return force

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
        if self.compensation is None:
            return sample
        wrench = self.compensation(sample.wrench, self.reached_pose())
        return dataclasses.replace(sample, wrench=wrench)  # keeps its time, counter, flags

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


def _xyz(pose: Pose) -> tuple[float, float, float]:
    """A pose's position (x, y, z), mm, as plain floats."""
    return (float(pose.x_mm), float(pose.y_mm), float(pose.z_mm))
