"""The path task: a taught path over a curved part, a force along the tool's axis, learned.

The second task kind (docs/tasks.md, docs/path.md), FC Pressure's job on a robot
with position control only. Its parts:

=====================================  ==============================================
:mod:`~forcelearn.tasks.path_spec`     the ``[task]`` keys, the path read and checked
:mod:`~forcelearn.tasks.evaluation`    r = |F − F_d| / tolerance, failure above 1
:mod:`~forcelearn.tasks.path_probe`    the probe pass and the learner's warm start
this module                            :class:`PathTask`: a pass over the points
=====================================  ==============================================

A pass (one trial of the trainer): from the retreat of the last pass the tool
goes back over the path lifted by ``approach_mm`` along each point's force axis
(free space), to the first point's approach pose; there it tares (the
calibration follows the orientation), moves in along the force axis in
``contact_step_mm`` steps until the force passes the contact threshold
(``contact_threshold_pct`` of the force), then each step k presses at point k
with the learner's offset along the force axis (mm, > 0 deeper), measures the
filtered force and is evaluated. The first step ramps the force: it moves in
steps whose force rise stays under ``force_ramp_n_s`` at the cell's pace. The
pass ends after the last point, or at a failure, with a retreat of
``retreat_mm`` along the force axis.

The learner's input is the point's index (the position along the path), one
box per point; its output the offset, ``AffineOutput(scale, 0, ±max_deviation_mm)``:
the command is clipped to ``max_deviation_mm``, so no move goes further from
the taught path along the force axis (FC Pressure's ``PosSupvDist``).

**Contact lost** where contact is expected (the force below the threshold at a
point): the point is recorded (:attr:`PathTask.lost_points`); with
``on_contact_loss = "retreat"`` the step fails and the pass ends with the
retreat; with ``"continue"`` the step counts as r = 1 (the edge of the band:
not a failure) and the pass goes on at the next point. It never chases the
surface beyond ``max_deviation_mm``.

Safety on every move, as the §5 task: the driver refuses a step above
``safety.max_step_mm`` or a target outside the workspace before sending
anything; every move towards the part is guarded (one sample per step against
``safety.max_force_n``), and, with a press guard on the cell
(:mod:`forcelearn.press_guard`), bounded from the last trusted reading along the
point's force axis (the guard's press direction follows the tool); the sensor's
watchdog raises on stale samples.

**First contact, checked** (``verify_contact``): a bias step exactly at a
pass's first contact (the first reading above the contact threshold after the
pass's tare) has no earlier reading of this zero to be compared with. It is
compared with the last pass's reading at the same offset, as is every reading of
the search before it (the contact search steps from the same place every pass, so
the offsets repeat): none may be lower by more than
:func:`~forcelearn.press_guard.press_agreement_n` of it (a step down is what would
let the press guard trust a low reading; a step up reads high, which the guard takes
as more force, and the pass's end zero check finds it). Where the last
pass has no reading there (the probe, the first pass, a search that moved) the
contact is **pressed twice**: the tool backs out to the approach pose (free
space), the zero is checked there (``zero_check``: it raises when the zero moved)
and it presses to the same offset again: the second reading must be within
:func:`~forcelearn.press_guard.press_agreement_n` of the first. Else
:class:`~forcelearn.errors.SensorSuspect` (the run retracts, re-zeroes in free
space and runs the pass again). Leaving the foam between the two presses costs
the foam a load cycle (the emulated foam wears a pass's worth each time the
tool leaves it), which is why a pass with a reading to compare with does not.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from forcelearn.devices import Pose
from forcelearn.errors import SensorSuspect
from forcelearn.learning import BoxGrid, Dimension
from forcelearn.paths import TaughtPath
from forcelearn.paths.taught import rotation_from_wxyz
from forcelearn.press_guard import MIN_STEP_MM, press_agreement_n
from forcelearn.tasks.approach import FineApproach
from forcelearn.tasks.evaluation import FAILURE_R
from forcelearn.tasks.path_spec import PathTaskSpec
from forcelearn.tasks.surface import SurfaceCell, read_after
from forcelearn.trainer import StepOutcome

CONTACT_STEP_MM = 1.0
"""Step along the force axis while looking for the first contact, mm (assumption: a tenth
of the foam a site presses; FC Pressure approaches at v5-v30)."""
PATH_APPROACH_ADVICE = (
    "lower [task] contact_threshold_pct or raise desired_force_n (the probe pass reads from the "
    "contact threshold to the desired force; its contact search steps no finer than that)")
"""What :class:`~forcelearn.tasks.approach.ApproachTooCoarse` tells a path run to set."""
CONTACT_MARGIN_MM = 3.0
"""Once the contact's offset is known, the search starts this far short of it, mm."""
RETURN_POINTS = 8
"""Most lifted points the return to the start passes through (free space)."""
RAMP_FIRST_STEP_S = 0.05
"""Time assumed for the ramp's first step, s (then each step's own)."""
WEAR_GAIN = 0.5
"""Share of a pass's mean force error the output's shift corrects after the pass (the wear
moves every point alike; half a correction a pass follows it without chasing noise)."""
MIN_RAMP_STEP_MM = 0.1
"""Smallest step of the force ramp, mm (a smaller one costs moves and changes nothing)."""


PathCell = SurfaceCell
"""What the path task needs of a cell: the §5 task's cell (:class:`forcelearn.cell.Cell` is one;
tests fake it); its ``measure_force_n`` is the force along the task's force axis."""


class PathGeometry:
    """The points of a pass: positions (mm), orientations and the world force axis of each."""

    def __init__(self, path: TaughtPath, force_axis: tuple[float, float, float]) -> None:
        self.path = path
        self.positions_mm = np.array(path.positions_mm)
        self.quaternions = [tuple(float(v) for v in q) for q in path.quaternions_wxyz]
        self.axes = rotation_from_wxyz(path.quaternions_wxyz).apply(np.asarray(force_axis))

    def __len__(self) -> int:
        return len(self.positions_mm)

    def pose(self, k: int, offset_mm: float) -> Pose:
        """Point k moved ``offset_mm`` along its force axis (> 0: into the part)."""
        x, y, z = (float(v) for v in self.positions_mm[k] + offset_mm * self.axes[k])
        q = self.quaternions[k]
        return Pose(x, y, z, (q[0], q[1], q[2], q[3]))


def path_grid(points: int) -> BoxGrid:
    """One box per point of the pass: the input is the point's index."""
    return BoxGrid([Dimension("point", -0.5, points - 0.5, points)])


class PathOffsetOutput:
    """y(a) = shift + scale · a, mm along the force axis, clipped to ±``max_deviation_mm``.

    ``shift_mm`` follows the wear (the foam sinks and softens pass after pass, at
    every point alike): after each pass :meth:`follow` moves it by ``WEAR_GAIN`` of
    the pass's mean force error over the points in contact, through the probe's
    stiffness; the learner's μ keeps what differs from point to point.
    """

    def __init__(self, scale_mm: float, max_deviation_mm: float, shift_mm: float = 0.0) -> None:
        self.scale_mm = scale_mm
        self.max_deviation_mm = max_deviation_mm
        self.shift_mm = shift_mm

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The offset command (mm) of action ``a``."""
        limit = self.max_deviation_mm
        return np.clip(self.shift_mm + self.scale_mm * np.asarray(a, dtype=float), -limit, limit)

    def follow(self, mean_error_n: float, stiffness_n_per_mm: float) -> None:
        """Move the shift against a pass's mean force error (N), within ±max_deviation_mm."""
        limit = self.max_deviation_mm
        change = -WEAR_GAIN * mean_error_n / stiffness_n_per_mm
        self.shift_mm = float(np.clip(self.shift_mm + change, -limit, limit))


def offset_output(scale_mm: float, max_deviation_mm: float) -> PathOffsetOutput:
    """The output map of a path task (:class:`PathOffsetOutput`, no shift yet)."""
    return PathOffsetOutput(scale_mm, max_deviation_mm)


class PathTask:
    """The path task on a cell (module docstring); an episodic task of the trainer."""

    name = "path"

    def __init__(self, cell: PathCell, spec: PathTaskSpec, path: TaughtPath, max_step_mm: float,
                 stiffness_n_per_mm: float, output: PathOffsetOutput | None = None,
                 verify_contact: bool = False,
                 zero_check: Callable[[], None] | None = None) -> None:
        self.cell = cell
        self.verify_contact = verify_contact
        """Check each pass's contact search up to its first contact (the module docstring)."""
        self.zero_check = zero_check
        """Called in free space between the two presses: raises when the zero moved."""
        self.contact_checks: list[tuple[float, float]] = []
        """(first, second) reading of every first contact pressed twice in this session, N."""
        self.contact_compared: list[tuple[float, float]] = []
        """(last pass's, this pass's) reading of every contact-search reading compared with the
        last pass's at its offset in this session, N."""
        self.last_contact_readings: list[tuple[float, float]] = []
        """The last contact search's (offset mm, force N) readings (in the task's state)."""
        self.output = output
        """The learner's output map, whose shift follows the wear after each pass (None: none)."""
        self._errors: list[float] = []
        self.spec = spec
        self.points = PathGeometry(path, spec.force_axis)
        self.max_step_mm = max_step_mm
        self.stiffness_n_per_mm = stiffness_n_per_mm
        """The foam's stiffness the force ramp's steps are sized by, N/mm (the probe's)."""
        self.steps_per_trial = len(self.points)
        self.desired_force_n = spec.desired_force_n
        self.evaluation = spec.evaluation
        self.grid = path_grid(len(self.points))
        self.start_force_n = math.nan
        self.contact_offset_mm: float | None = None
        """Where point 0's contact began on the last probe, mm (None: unknown, search from
        the approach pose)."""
        self.first_contact_peak_n = math.nan
        """The largest force of the last pass's first contact and ramp, N."""
        self.lost_points: list[tuple[int, int]] = []
        """(pass, point) of every contact lost where contact was expected."""
        self.largest_offset_mm = 0.0
        """The largest |offset| a pressing move of the task commanded, mm."""
        self.passes = 0
        self._step = len(self.points) - 1
        """The point the tool is at (or was last: where the return to the start begins)."""
        self._offset = 0.0
        self._trial_start_s = 0.0

    def state_dict(self) -> dict[str, Any]:
        """What a pass leaves behind (JSON-safe): counters, the contact found, the wear shift."""
        return {
            "passes": self.passes, "step": self._step, "offset_mm": self._offset,
            "lost_points": [list(p) for p in self.lost_points],
            "largest_offset_mm": self.largest_offset_mm,
            "first_contact_peak_n": self.first_contact_peak_n,
            "contact_offset_mm": self.contact_offset_mm,
            "stiffness_n_per_mm": self.stiffness_n_per_mm,
            "start_force_n": self.start_force_n,
            "shift_mm": self.output.shift_mm if self.output is not None else 0.0,
            "contact_readings": [list(r) for r in self.last_contact_readings],
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` (a resumed run, or a pass rolled back after a fault)."""
        self.passes, self._step = int(state["passes"]), int(state["step"])
        self._offset = float(state["offset_mm"])
        self.lost_points = [(int(a), int(b)) for a, b in state["lost_points"]]
        self.largest_offset_mm = float(state["largest_offset_mm"])
        self.first_contact_peak_n = float(state["first_contact_peak_n"])
        contact = state["contact_offset_mm"]
        self.contact_offset_mm = None if contact is None else float(contact)
        self.stiffness_n_per_mm = float(state["stiffness_n_per_mm"])
        self.start_force_n = float(state["start_force_n"])
        if self.output is not None:
            self.output.shift_mm = float(state["shift_mm"])
        self.last_contact_readings = [(float(o), float(f))
                                      for o, f in state.get("contact_readings", [])]

    def away(self, here: Pose) -> Pose:
        """Free space from ``here``: back along its force axis to ``approach_mm`` off the path.

        The nearest point's offset along the axis (how deep ``here`` presses) plus the
        approach: a fault's retract (:mod:`forcelearn.tasks.recovery`), the tool's own axis
        as the pose turns it.
        """
        where = np.array([here.x_mm, here.y_mm, here.z_mm])
        k = int(np.argmin(np.linalg.norm(self.points.positions_mm - where, axis=1)))
        axis = rotation_from_wxyz(np.array([here.quaternion])).apply(
            np.asarray(self.spec.force_axis))[0]
        depth = float((where - self.points.positions_mm[k]) @ axis)
        back = max(0.0, depth + self.spec.approach_mm)
        x, y, z = (float(v) for v in where - back * axis)
        return Pose(x, y, z, here.quaternion)

    @property
    def trial_cell_time_s(self) -> float:
        """Cell time since the present pass began, s."""
        return self.cell.time_s - self._trial_start_s

    def move_to_point(self, k: int, offset_mm: float, guard: bool = True,
                      pressing: bool = False) -> None:
        """Move to point k, ``offset_mm`` along its force axis (guarded: one sample a step).

        ``pressing``: a move that presses the path (a step, the ramp, the probe), whose offset
        ``max_deviation_mm`` bounds (approach and retreat are set by their own keys).
        """
        self._step, self._offset = k, offset_mm
        if pressing:
            self.largest_offset_mm = max(self.largest_offset_mm, abs(offset_mm))
        press_guard = getattr(self.cell, "press_guard", None)
        if press_guard is not None:  # the guard presses along this point's force axis
            x, y, z = (float(v) for v in self.points.axes[k])
            press_guard.direction = (x, y, z)
        self.cell.move_in_steps(self.points.pose(k, offset_mm), self.max_step_mm,
                                guard_force=guard)

    def retreat(self) -> None:
        """Back off ``retreat_mm`` along the force axis from the present point."""
        self.cell.stage = ("retreat", 0)
        k = min(self._step, len(self.points) - 1)
        self.move_to_point(k, -self.spec.retreat_mm, guard=False)

    def return_to_start(self) -> None:
        """Go back over the path, lifted by ``approach_mm``, to the first point's approach pose."""
        self.cell.stage = ("approach", 0)
        n = len(self.points)
        stride = max(1, math.ceil(n / RETURN_POINTS))
        for k in [*range(min(self._step, n - 1), 0, -stride), 0]:
            self.move_to_point(k, -self.spec.approach_mm, guard=False)

    def reset(self) -> np.ndarray:
        """Return to the start, tare in free space, find the first contact; input of point 0."""
        self.cell.sync()
        self._trial_start_s = self.cell.time_s
        self.return_to_start()  # from the point where the last pass ended
        self.tare()
        self._errors = []
        readings = self.find_contact()
        self.start_force_n = readings[-1][1]
        self.first_contact_peak_n = max(force for _, force in readings)
        return np.array([0.0])

    def tare(self) -> None:
        """Zero the sensor here (free space), then check it with a burst (``zero_check``).

        The sensor's own zero is of its few samples (one sample's noise on the JR3); the
        check's burst mean becomes the zero (in software), which narrows every later zero
        check's bound (the pass's end: from about 0.9 N to 0.45-0.49 N on the emulated JR3).
        """
        self.cell.tare(self.spec.contact_force_n)
        if self.zero_check is not None:
            self.zero_check()

    def find_contact(self, until_n: float | None = None) -> list[tuple[float, float]]:
        """Step in along point 0's force axis; (offset mm, force N) of every step.

        From the approach pose (or ``CONTACT_MARGIN_MM`` short of a known contact) until
        the force passes ``until_n`` (default: the contact threshold) or the offset
        reaches ``max_deviation_mm``. With ``until_n`` (the probe pass, whose readings fit
        the stiffness) a first contact met in too coarse a step is approached again finer
        (:mod:`forcelearn.tasks.approach`); a pass's search is not (measured on 8 N/mm at
        5 N: its passes then start at the threshold and never came in band).
        """
        self.cell.stage = ("contact", 0)
        self._step = 0
        self._offset = -self.spec.approach_mm
        limit_n = self.spec.contact_force_n if until_n is None else until_n
        deepest = self.spec.max_deviation_mm
        hint = self.contact_offset_mm
        if hint is not None and hint - CONTACT_MARGIN_MM > self._offset:  # known: go near it
            self.move_to_point(0, min(hint - CONTACT_MARGIN_MM, deepest))
        self.cell.reset_filter()
        verify = self.verify_contact
        readings = [(self._offset, self.cell.measure_force_n())]
        contact_n = self.spec.contact_force_n
        approach = None if until_n is None else FineApproach(  # the probe pass's search
            CONTACT_STEP_MM, contact_n, until_n - contact_n, PATH_APPROACH_ADVICE,
            PATH_APPROACH_ADVICE)
        while True:
            if verify:
                readings[-1] = (self._offset, self.check_contact(readings[-1][1]))
                verify = readings[-1][1] < self.spec.contact_force_n
            step = self._contact_step_mm(CONTACT_STEP_MM if approach is None
                                         else approach.step_mm)
            if readings[-1][1] >= limit_n or self._offset >= deepest or step < MIN_STEP_MM:
                self.last_contact_readings = list(readings)
                return readings
            self._offset = min(self._offset + step, deepest)
            self.move_to_point(0, self._offset, pressing=self._offset > 0)
            readings.append((self._offset, self.cell.measure_force_n()))
            if approach is not None:
                self._refine(approach, readings)

    def _refine(self, approach: FineApproach, readings: list[tuple[float, float]]) -> None:
        """A first contact met in too coarse a step: back out to the free reading before it.

        The contact's reading is dropped; the search steps in again from there in
        ``approach.step_mm`` (:mod:`forcelearn.tasks.approach`).
        """
        (free_mm, free_n), (offset, force) = readings[-2], readings[-1]
        contact_n = self.spec.contact_force_n
        if not (free_n < contact_n <= force) or not approach.again(
                force, free_n, offset - free_mm, " at the path's first point"):
            return
        readings.pop()
        self.move_to_point(0, free_mm, pressing=free_mm > 0)

    def _contact_step_mm(self, step_mm: float = CONTACT_STEP_MM) -> float:
        """The contact search's next step, mm: ``step_mm``, or less.

        Less where the press guard allows less past the last reading (a stiff part near the
        limit): the step ends where its reading can stop the search, not in a cut move that
        goes on until the guard refuses it.
        """
        press_guard = getattr(self.cell, "press_guard", None)
        if press_guard is None:
            return step_mm
        return float(min(step_mm, press_guard.allowed_mm()))

    def check_contact(self, force_n: float) -> float:
        """A contact search's reading up to its first contact, checked; the reading to use, N.

        Compared with the last pass's reading at this offset (the module docstring); at the
        first contact, where the last pass has none, pressed twice (:meth:`press_again`).

        Raises:
            SensorSuspect: it reads lower than the last pass did here, or its two presses
                disagree, by more than :func:`~forcelearn.press_guard.press_agreement_n`
                (the robot is stopped).
        """
        before = [f for o, f in self.last_contact_readings if abs(o - self._offset) < 1e-9]
        if before:
            self.contact_compared.append((before[0], force_n))
            allowed = press_agreement_n(before[0])
            if force_n < before[0] - allowed:
                self._suspect(f"the contact search read {force_n:.2f} N at offset "
                              f"{self._offset:.2f} mm, where the last pass read "
                              f"{before[0]:.2f} N (more than {allowed:.2f} N less)")
            return force_n
        if force_n < self.spec.contact_force_n:
            return force_n
        return self.press_again(force_n)

    def _suspect(self, what: str) -> None:
        """Stop the robot and raise SensorSuspect about ``what``."""
        stop = getattr(self.cell, "stop", None)
        if stop is not None:
            stop()
        raise SensorSuspect(
            f"{what}: the sensor's zero moved at the contact, or the part moved; the run "
            "retracts, zeroes in free space and runs the pass again (if it repeats, check the "
            "sensor's cable and the part's fixture)")

    def press_again(self, first_n: float) -> float:
        """Back out to free space, check the zero, press point 0 again; the second reading, N.

        Raises:
            ZeroMoved: (from ``zero_check``) free space does not read the zero.
            SensorSuspect: the second reading differs from ``first_n`` by more than
                :func:`~forcelearn.press_guard.press_agreement_n` of it (the robot is stopped).
        """
        offset = self._offset
        self.move_to_point(0, -self.spec.approach_mm, guard=False)
        if self.zero_check is not None:
            self.zero_check()
        self.cell.stage = ("contact", 0)
        self.move_to_point(0, offset, pressing=offset > 0)
        self.cell.reset_filter()
        second = self.cell.measure_force_n()
        self.contact_checks.append((first_n, second))
        allowed = press_agreement_n(first_n)
        if abs(second - first_n) > allowed:
            self._suspect(f"the first contact read {first_n:.2f} N, pressed again at the same "
                          f"offset {second:.2f} N (more than {allowed:.2f} N apart)")
        return second

    def _ramp_to(self, offset_mm: float) -> float:
        """Press from the contact to ``offset_mm`` at point 0 under the force ramp; the peak, N.

        Each step's force rise (stiffness x step) over the time the last step took stays
        under ``force_ramp_n_s``.
        """
        peak, took_s = -math.inf, RAMP_FIRST_STEP_S
        while self._offset < offset_mm:
            step = max(MIN_RAMP_STEP_MM,
                       self.spec.force_ramp_n_s * took_s / self.stiffness_n_per_mm)
            self._offset = min(self._offset + step, offset_mm)
            before = self.cell.time_s
            self.move_to_point(0, self._offset, pressing=True)
            took_s = max(self.cell.time_s - before, RAMP_FIRST_STEP_S)
            peak = max(peak, self.cell.measure_force_n(1))
        return peak

    def step(self, command: np.ndarray) -> StepOutcome:
        """Press at the next point with the commanded offset (mm); evaluate the force."""
        k = self._step
        offset = float(command[0])
        self.cell.stage = ("step", k + 1)

        def moves() -> None:
            if k == 0 and offset > self._offset:
                self.first_contact_peak_n = max(self.first_contact_peak_n, self._ramp_to(offset))
            self.move_to_point(k, offset, pressing=True)

        force, limit_hit = read_after(self.cell, moves)
        judged = self.evaluation.evaluate(force, limit_hit)
        lost = (not limit_hit) and force < self.spec.contact_force_n
        r, failed = judged.r, judged.failed
        if lost:
            self.lost_points.append((self.passes, k))
            if self.spec.on_contact_loss == "continue":
                r, failed = min(r, FAILURE_R), False
        last = k == len(self.points) - 1
        if not (lost or limit_hit):
            self._errors.append(judged.force_error_n)
        if failed or last:
            self.retreat()
            self.passes += 1
            if self.output is not None and self._errors:
                self.output.follow(float(np.mean(self._errors)), self.stiffness_n_per_mm)
        x, y, z = (float(v) for v in self.points.positions_mm[k])
        extras = {"point": float(k), "offset_mm": offset, "contact_lost": float(lost),
                  "limit_hit": float(limit_hit), "x_mm": x, "y_mm": y, "z_mm": z}
        self._step = k if (failed or last) else k + 1
        return StepOutcome(np.array([float(min(k + 1, len(self.points) - 1))]), r, failed,
                           force, judged.force_error_n, extras)
