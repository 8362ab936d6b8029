"""Paper §5: force tracking on a sponge with the position-controlled robot, single input/output.

The tool starts pressed into the sponge at ``start`` and moves ``z_step_mm``
(−5 mm) per step for ``steps_per_trial`` (20) steps; learning commands the Y
position (normal to the sponge) at each step; the desired force is 2 kgf
(19.61 N). After a failure or a completed pass the robot retracts along +Y and
returns to the start for the next trial; the sponge wears with every pass.

Choices the paper leaves open (docs/surface.md gives the reasons):

* input: the distance travelled along Z (mm) before the step, in
  ``input_parts`` boxes over the path (one box per step by default);
* output y(a) = centre Y + scale · a (absolute Y command, mm), limited to
  ±half-range from the centre. Centre, scale and half-range come from the
  surface probe (:mod:`forcelearn.tasks.surface_probe`) unless the config
  gives them (``output_centre_y_mm``, ``output_scale_mm``, ``max_offset_mm``);
  with no probe and no config, the fallback is start Y, 2 mm and 15 mm;
* evaluation r = |force − desired| / tolerance (``tolerance_n``, by default
  half the desired force); a step with r > 1 fails, and so does passing the
  safety force limit (r is then set to 2 for learning).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import TypedDict

import numpy as np

from forcelearn.cell import Cell
from forcelearn.devices import IDENTITY_QUATERNION, STANDARD_GRAVITY_M_S2, Pose
from forcelearn.errors import ConfigError, ForceLimitExceeded
from forcelearn.learning import BoxGrid, Dimension
from forcelearn.trainer import StepOutcome

log = logging.getLogger(__name__)

KGF_N = STANDARD_GRAVITY_M_S2
"""One kilogram-force in newtons."""
SAFETY_R = 2.0
"""Evaluation given to a step stopped by the force limit (a failure, learned as one)."""
FALLBACK_SCALE_MM = 2.0
"""Output scale without a probe or a configured one, mm per action unit (the pre-probe map)."""
FALLBACK_OFFSET_MM = 15.0
"""Output half-range without a probe or a configured one, mm (the pre-probe map)."""


def _is_number(value: object) -> bool:
    """True for a finite int or float (not a bool, not a string, not NaN)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


MAX_SAMPLES_PER_STEP = 10_000
"""Most sensor samples one step may read (3.25 s of the JR3's SYNC rate, 1.4 s of Net F/T's)."""


@dataclass(frozen=True)
class SurfaceTaskSpec:
    """Targets, path, partition and output map of the §5 task (paper values as defaults).

    Keys left at ``None`` are derived: ``tolerance_n`` from the desired force,
    the output map (``output_centre_y_mm``, ``output_scale_mm``,
    ``max_offset_mm``) from the surface probe at the start of a run.
    """

    desired_force_n: float = 2.0 * KGF_N
    """2 kgf (§5)."""
    tolerance_n: float | None = None
    """Force error at which r = 1 (a failure), N; default half the desired force (§5's 10 N
    for 2 kgf, rounded)."""
    steps_per_trial: int = 20
    z_step_mm: float = -5.0
    start_mm: tuple[float, float, float] = (900.0, -4.0, 0.0)
    """Start pose position: x, y (4 mm into the fresh sponge), z."""
    orientation: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0)
    """Tool orientation quaternion (w, x, y, z): tool pointing down."""
    retract_y_mm: float = 15.0
    """Y of the retract path: 10 mm clear of the highest point of the default sponge."""
    input_parts: int = 20
    output_centre_y_mm: float | None = None
    """Y command (mm) at action 0; default from the probe (else start Y)."""
    output_scale_mm: float | None = None
    """Millimetres of Y command per action unit; default from the probe (else 2 mm)."""
    max_offset_mm: float | None = None
    """Largest |Y command − centre|, mm; default from the probe (else 15 mm)."""
    samples_per_step: int = 0
    """Sensor samples filtered after each move; 0: as many as fit ``measurement_window_s``."""
    measurement_window_s: float = 0.025
    """Time the burst of samples after each settled move spans, s (0.2 N adapter noise with
    1.3 ms correlation: a 25 ms burst filters to ~0.06 N; see docs/results/filter.md)."""
    settle_s: float = 0.05
    """Dwell in position before the force is measured, s (the robot's clock)."""
    tare_each_trial: bool = False
    """Zero the sensor in free space, above the start at the retract Y, before each trial's
    press: the sensor's bias drift then never reaches the force the learner controls (off:
    the paper's setup, zeroed once when the sensor opens)."""
    tare_max_reading_n: float = 2.0
    """A tare is refused (warned) when the free-space normal force reads more than this, N."""

    def __post_init__(self) -> None:
        for name in ("steps_per_trial", "input_parts", "samples_per_step"):
            value = getattr(self, name)
            least = 0 if name == "samples_per_step" else 1  # 0: from the measurement window
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ConfigError(f"task.{name} = {value!r}: must be a whole number >= {least}")
        if self.samples_per_step > MAX_SAMPLES_PER_STEP:
            raise ConfigError(
                f"task.samples_per_step = {self.samples_per_step}: at most "
                f"{MAX_SAMPLES_PER_STEP} (each step reads and filters them all)"
            )
        if not isinstance(self.tare_each_trial, bool):
            raise ConfigError(f"task.tare_each_trial = {self.tare_each_trial!r}: true or false")
        positive = ("desired_force_n", "tolerance_n", "output_scale_mm", "max_offset_mm",
                    "tare_max_reading_n")
        for name in positive:
            value = getattr(self, name)
            if value is not None and not (_is_number(value) and value > 0):
                raise ConfigError(f"task.{name} = {value!r}: must be a finite number > 0")
        for name in ("settle_s",):
            value = getattr(self, name)
            if not (_is_number(value) and value >= 0):
                raise ConfigError(f"task.{name} = {value!r}: must be a finite number >= 0")
        window = self.measurement_window_s
        if not (_is_number(window) and window > 0):
            raise ConfigError(
                f"task.measurement_window_s = {window!r}: must be a finite number > 0"
            )
        for name in ("z_step_mm", "retract_y_mm", "output_centre_y_mm"):
            value = getattr(self, name)
            if value is not None and not _is_number(value):
                raise ConfigError(f"task.{name} = {value!r}: must be a finite number")
        for name, size in (("start_mm", 3), ("orientation", 4)):
            value = getattr(self, name)
            if not (
                isinstance(value, tuple) and len(value) == size and all(map(_is_number, value))
            ):
                raise ConfigError(f"task.{name} = {value!r}: must be {size} finite numbers")
        if self.z_step_mm == 0:
            raise ConfigError("task.z_step_mm must not be 0")
        if self.retract_y_mm <= self.fallback_centre_y_mm + self.fallback_offset_mm:
            raise ConfigError(
                f"task.retract_y_mm = {self.retract_y_mm:g} mm must lie beyond the output "
                "range's top (centre + task.max_offset_mm = "
                f"{self.fallback_centre_y_mm + self.fallback_offset_mm:g} mm)"
            )

    @property
    def tolerance(self) -> float:
        """The force error at which r = 1, N (``tolerance_n`` or half the desired force)."""
        return self.tolerance_n if self.tolerance_n is not None else 0.5 * self.desired_force_n

    @property
    def map_configured(self) -> bool:
        """True when the config gives the whole output map (the probe then chooses nothing)."""
        return None not in (self.output_centre_y_mm, self.output_scale_mm, self.max_offset_mm)

    @property
    def fallback_centre_y_mm(self) -> float:
        """Centre of the output map without a probe: the configured one, else start Y."""
        return self.start_mm[1] if self.output_centre_y_mm is None else self.output_centre_y_mm

    @property
    def fallback_offset_mm(self) -> float:
        """Half-range of the output map without a probe (15 mm unless configured)."""
        return FALLBACK_OFFSET_MM if self.max_offset_mm is None else self.max_offset_mm

    @property
    def fallback_scale_mm(self) -> float:
        """Scale of the output map without a probe (2 mm unless configured)."""
        return FALLBACK_SCALE_MM if self.output_scale_mm is None else self.output_scale_mm

    def samples_for(self, sample_period_s: float) -> int:
        """Samples per step: the configured count, or as many as fit the measurement window."""
        if self.samples_per_step:
            return self.samples_per_step
        count = max(1, round(self.measurement_window_s / sample_period_s))
        if count > MAX_SAMPLES_PER_STEP:
            raise ConfigError(
                f"task.measurement_window_s = {self.measurement_window_s:g} s holds {count} "
                f"samples of filter.sample_period_s = {sample_period_s:g} s, more than "
                f"{MAX_SAMPLES_PER_STEP} a step: shorten the window"
            )
        return count

    @property
    def path_mm(self) -> float:
        """Length of the path along Z, mm."""
        return abs(self.z_step_mm) * self.steps_per_trial

    def grid(self) -> BoxGrid:
        """The BOXES partition of the distance travelled (one box per step by default)."""
        half = 0.5 * self.path_mm / self.input_parts
        return BoxGrid([Dimension("travel_mm", -half, self.path_mm - half, self.input_parts)])

    def start_pose(self) -> Pose:
        """The pose each trial starts from."""
        return Pose(*self.start_mm, self.orientation or IDENTITY_QUATERNION)


RECENTRE_SHARE = 0.5
"""The range is re-centred on the learner once the mean of its μ passes this share of the
half-range (:meth:`SurfaceYOutput.recentre_on`)."""
WEAR_GAIN = 0.5
"""Share of the start press's depth error corrected per trial when the map follows wear."""


def step_centre_y_mm(path_y_mm: tuple[float, ...], centre_y_mm: float, step_index: int) -> float:
    """The centre Y (mm) of step ``step_index`` (0: the first) of an output map.

    The path's, held at its ends, or ``centre_y_mm`` for a map with no path.
    """
    if not path_y_mm:
        return centre_y_mm
    return path_y_mm[min(max(step_index, 0), len(path_y_mm) - 1)]


class TrialTrace(TypedDict):
    """What a run keeps of each trial's Y commands (mm)."""

    mean_y_mm: list[float]
    """The mean Y (y of μ) of every step."""
    command_y_mm: list[float]
    """The searched Y command of every step."""
    shift_mm: float
    """How far the range's centre had moved when the trial ran (mm): the wear shift plus the
    re-centring on the learner (0: a map that moved neither way)."""
    force_n: list[float]
    """The filtered force of every step, N (NaN: a checkpoint from before it was kept)."""


class SurfaceYOutput:
    """y(a, x) = centre Y (of the step) + scale · a, limited to ±max_offset: a Y command in mm.

    With ``path_y_mm`` (one centre per step, the surface probe's path) the
    centre follows the surface: the step is the one that starts at the
    travel ``x`` (mm), x / ``step_mm``. With ``wear_stiffness_n_per_mm`` set
    (every map the probe chose) the map also follows the sponge's wear:
    :class:`SurfaceTask` moves :attr:`shift_mm` (added to every centre and to
    the start press) from each trial's start force (:meth:`track_wear`).
    """

    def __init__(
        self,
        start_y_mm: float,
        scale_mm: float,
        max_offset_mm: float,
        path_y_mm: tuple[float, ...] = (),
        step_mm: float = 5.0,
        start_press_y_mm: float | None = None,
        wear_stiffness_n_per_mm: float | None = None,
        shift_range_mm: tuple[float, float] | None = None,
        wear_reference_n: float | None = None,
    ):
        self.start_y_mm = start_y_mm
        """The centre Y (mm): the command at action 0 (the mean centre with a path)."""
        self.scale_mm = scale_mm
        self.max_offset_mm = max_offset_mm
        self.path_y_mm = tuple(path_y_mm)
        self.step_mm = step_mm
        self.start_press_y_mm = start_press_y_mm
        """Y of each trial's start press before any shift (None: the task's ``start_mm``)."""
        self.wear_stiffness_n_per_mm = wear_stiffness_n_per_mm
        """The stiffness that turns a start-force error into a shift (None: no tracking)."""
        self.shift_mm = 0.0
        """How far the sponge has moved since the probe, as tracked (mm, − deeper)."""
        self.shift_range_mm = shift_range_mm
        """Least and most shift (mm); a wear that would move the map further is not followed."""
        self.wear_reference_n = wear_reference_n
        """The start force the tracking holds (N): the first trial's (None: not yet read)."""
        self.held_mm = 0.0
        """How far the last tracked shift passed :attr:`shift_range_mm` (mm, − deeper)."""
        self.recentre_mm = 0.0
        """How far the range has been re-centred on the learner's drift (mm, − deeper;
        :meth:`recentre_on`): moves every centre, not the start press."""
        self._held = False

    @property
    def displacement_mm(self) -> float:
        """How far the range's centre has moved since the probe (mm): wear shift + re-centring."""
        return self.shift_mm + self.recentre_mm

    def centre_of_step(self, step_index: int) -> float:
        """The centre Y (mm) of step ``step_index`` (0: the first), shift included."""
        return step_centre_y_mm(self.path_y_mm, self.start_y_mm, step_index) + self.displacement_mm

    def centre_at(self, x: np.ndarray | None) -> float:
        """The centre Y (mm) of the step that starts at travel ``x`` (mm), shift included."""
        if not self.path_y_mm or x is None or np.size(x) == 0:
            return self.start_y_mm + self.displacement_mm
        return self.centre_of_step(round(float(np.ravel(x)[0]) / self.step_mm))

    def command_at_step(self, a: float, step_index: int) -> float:
        """The Y command (mm) for action ``a`` at step ``step_index`` (0: the first)."""
        travel = np.array([step_index * self.step_mm])
        return float(self(np.array([a]), travel)[0])

    def track_wear(self, start_force_n: float) -> None:
        """Move :attr:`shift_mm` by ``WEAR_GAIN`` × the start-force error / stiffness.

        The reference is the first trial's start force (the same press and the
        same settle every trial, so the foam's relaxation reads the same): less
        force means the surface has sunk (set) or softened, so the map and the
        start press go deeper by the depth that force is missing (a half step
        per trial, against the sensor's noise), never past
        :attr:`shift_range_mm` (the allowed depth and the retract plane; a
        warning says so once, :attr:`held_mm` keeps by how much).
        """
        k = self.wear_stiffness_n_per_mm
        if k is None or not math.isfinite(start_force_n):
            return
        if self.wear_reference_n is None:
            self.wear_reference_n = start_force_n
            return
        shift = self.shift_mm + WEAR_GAIN * (start_force_n - self.wear_reference_n) / k
        self.held_mm = 0.0
        if self.shift_range_mm is not None:
            low, high = self.shift_range_mm  # bounds the whole displacement, re-centring too
            low, high = low - self.recentre_mm, high - self.recentre_mm
            held = min(max(shift, low), high)
            self.held_mm = shift - held
            if held != shift and not self._held:
                self._held = True  # once a run
                log.warning(
                    "the map would follow the sponge's wear %.2f mm %s than allowed "
                    "(probe.max_depth_mm, safety.workspace_min_mm, task.retract_y_mm): held at "
                    "the limit", abs(shift - held), "deeper" if shift < low else "higher",
                )
            shift = held
        self.shift_mm = shift

    def recentre_on(self, means: np.ndarray) -> float:
        """Re-centre the range on the learner's drift; return the move (mm, 0: none).

        ``means`` are the learner's μ of every box (action units, changed in
        place). When their mean sits beyond ``RECENTRE_SHARE`` of the
        half-range, the range's centre moves by that drift and every μ loses
        it, so each command stays the same (y = centre + scale · μ) while the
        range's ends move with what the learner found: a sponge whose wear the
        start press does not show (softening deep below the start press's
        depth) no longer pins the learner at an edge. Maps without wear
        tracking (a configured one, no probe) are never moved; the whole
        displacement stays within :attr:`shift_range_mm`.
        """
        if self.wear_stiffness_n_per_mm is None or self.shift_range_mm is None:
            return 0.0
        drift_mm = float(np.mean(means)) * self.scale_mm
        if abs(drift_mm) < RECENTRE_SHARE * self.max_offset_mm:
            return 0.0
        low, high = self.shift_range_mm
        now = self.displacement_mm
        move = min(max(now + drift_mm, low), high) - now
        if move == 0.0:
            return 0.0
        self.recentre_mm += move
        means -= move / self.scale_mm
        log.info("the output range follows the learner's drift: re-centred %+.2f mm (%+.2f mm "
                 "in all)", move, self.recentre_mm)
        return move

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Return the Y command (mm) for action ``a`` at travel ``x``."""
        offset = np.clip(a * self.scale_mm, -self.max_offset_mm, self.max_offset_mm)
        return self.centre_at(x) + offset


class SurfaceTask:
    """The §5 episodic task on a :class:`~forcelearn.cell.Cell` (emulated or real)."""

    name = "surface"

    def __init__(
        self,
        cell: Cell,
        spec: SurfaceTaskSpec,
        max_step_mm: float,
        output: SurfaceYOutput | None = None,
    ):
        self.cell = cell
        self._output = output
        self.spec = spec
        self.max_step_mm = max_step_mm
        self.steps_per_trial = spec.steps_per_trial
        self.desired_force_n = spec.desired_force_n
        self.grid = spec.grid()
        self.start_force_n = math.nan
        self._step = 0
        self._trial_start_s = 0.0

    def output_map(self) -> SurfaceYOutput:
        """The output function y this task expects the learner to use.

        The map given at construction (the probe's choice), else the configured
        or fallback one (:meth:`SurfaceTaskSpec.fallback_centre_y_mm` ...).
        """
        if self._output is not None:
            return self._output
        spec = self.spec
        return SurfaceYOutput(
            spec.fallback_centre_y_mm, spec.fallback_scale_mm, spec.fallback_offset_mm
        )

    def retract(self) -> None:
        """Pull out along +Y to the retract plane (in limited steps)."""
        self.cell.stage = ("retreat", 0)
        pose = self.cell.pose
        self.cell.move_in_steps(
            Pose(pose.x_mm, self.spec.retract_y_mm, pose.z_mm, pose.quaternion), self.max_step_mm
        )

    @property
    def trial_cell_time_s(self) -> float:
        """Cell time (the robot's clock, s) since the present trial began."""
        return self.cell.time_s - self._trial_start_s

    def start_pose(self) -> Pose:
        """Where each trial presses in: ``start_mm`` or the map's start press, + its shift."""
        start = self.spec.start_pose()
        output = self._output
        if output is None:
            return start
        press_y = start.y_mm if output.start_press_y_mm is None else output.start_press_y_mm
        return Pose(start.x_mm, press_y + output.shift_mm, start.z_mm, start.quaternion)

    def reset(self) -> np.ndarray:
        """Retract, travel clear of the sponge to above the start, press in, measure the force.

        Starts from the controller's commanded target (:meth:`Cell.sync`), so a
        resumed run starts exactly as the uninterrupted one would.
        """
        start = self.start_pose()
        self.cell.sync()
        self._trial_start_s = self.cell.time_s
        self.retract()
        self.cell.stage = ("approach", 0)
        self.cell.move_in_steps(
            Pose(start.x_mm, self.spec.retract_y_mm, start.z_mm, start.quaternion),
            self.max_step_mm,
        )
        if self.spec.tare_each_trial:
            self.cell.tare(self.spec.tare_max_reading_n)
        self.cell.move_in_steps(start, self.max_step_mm, guard_force=True)
        self.cell.reset_filter()
        self.start_force_n = self.cell.measure_force_n()
        if self._output is not None:
            self._output.track_wear(self.start_force_n)
        self._step = 0
        return np.array([0.0])

    def step(self, command: np.ndarray) -> StepOutcome:
        """Advance one Z step to the commanded Y; evaluate the filtered force."""
        start = self.spec.start_pose()
        self._step += 1
        travel = self._step * abs(self.spec.z_step_mm)
        y_cmd = float(command[0])
        target = Pose(
            start.x_mm, y_cmd, start.z_mm + self._step * self.spec.z_step_mm, start.quaternion
        )
        self.cell.stage = ("step", self._step)
        try:
            self.cell.move_in_steps(target, self.max_step_mm, guard_force=True)
            force = self.cell.measure_force_n()
            error = force - self.desired_force_n
            r = abs(error) / self.spec.tolerance
            limit_hit = False
        except ForceLimitExceeded:
            force = self.cell.force_filter.force_n
            error = force - self.desired_force_n
            r = SAFETY_R
            limit_hit = True
        failed = r > 1.0 or limit_hit
        if failed or self._step == self.steps_per_trial:
            self.retract()
        extras = {"y_cmd_mm": y_cmd, "z_mm": target.z_mm, "limit_hit": float(limit_hit)}
        return StepOutcome(np.array([travel]), r, failed, force, error, extras)


def check_task_limits(
    spec: SurfaceTaskSpec,
    max_force_n: float,
    workspace_min_mm: tuple[float, float, float],
    workspace_max_mm: tuple[float, float, float],
) -> None:
    """Refuse a task the safety limits make impossible, before any device opens.

    Checks the desired force against the force limit, and the path (start,
    end, retract plane) and any configured output range against the
    workspace box (mm). Raises :class:`ConfigError` naming the key.
    """
    if spec.desired_force_n >= max_force_n:
        raise ConfigError(
            f"task.desired_force_n = {spec.desired_force_n:g} N is at or above "
            f"safety.max_force_n = {max_force_n:g} N: every trial would stop at the limit; "
            "lower the desired force (or raise the limit if the cell allows)"
        )
    lo, hi = workspace_min_mm, workspace_max_mm
    x, y, z = spec.start_mm
    end_z = z + spec.steps_per_trial * spec.z_step_mm

    def inside(key: str, axis: int, value: float) -> None:
        if not lo[axis] <= value <= hi[axis]:
            name = "xyz"[axis]
            raise ConfigError(
                f"{key}: {name} = {value:g} mm lies outside the workspace "
                f"[{lo[axis]:g}, {hi[axis]:g}] mm (safety.workspace_min_mm/max_mm)"
            )

    inside("task.start_mm", 0, x)
    inside("task.start_mm", 1, y)
    inside("task.start_mm", 2, z)
    inside("task.z_step_mm (path end = start z + steps_per_trial * z_step_mm)", 2, end_z)
    inside("task.retract_y_mm", 1, spec.retract_y_mm)
    if spec.max_offset_mm is not None or spec.output_centre_y_mm is not None:
        centre, half = spec.fallback_centre_y_mm, spec.fallback_offset_mm
        key = "task.max_offset_mm" if spec.max_offset_mm is not None else "task.output_centre_y_mm"
        inside(f"{key} (output range bottom = centre - max_offset)", 1, centre - half)
        inside(f"{key} (output range top = centre + max_offset)", 1, centre + half)
