"""Paper §5: what the force-tracking task on a sponge is: its targets, path, partition and band.

The tool starts pressed into the sponge at ``start`` and moves ``z_step_mm``
(−5 mm) per step for ``steps_per_trial`` (20) steps; learning commands the Y
position (normal to the sponge) at each step; the desired force is 2 kgf
(19.61 N), evaluated by :class:`~forcelearn.tasks.evaluation.ForceEvaluation`
with ``tolerance_n`` (by default half the desired force).
:class:`~forcelearn.tasks.surface.SurfaceTask` runs it on a cell;
docs/surface.md gives the reasons for the choices the paper leaves open.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from forcelearn.devices import IDENTITY_QUATERNION, STANDARD_GRAVITY_M_S2, Pose
from forcelearn.errors import ConfigError
from forcelearn.learning import BoxGrid, Dimension
from forcelearn.tasks.evaluation import ForceEvaluation

KGF_N = STANDARD_GRAVITY_M_S2
"""One kilogram-force in newtons."""
FALLBACK_SCALE_MM = 2.0
"""Output scale without a probe or a configured one, mm per action unit (the pre-probe map)."""
FALLBACK_OFFSET_MM = 15.0
"""Output half-range without a probe or a configured one, mm (the pre-probe map)."""


def _is_number(value: object) -> bool:
    """True for a finite int or float (not a bool, not a string, not NaN)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


APPROACHES = ("auto", "loading", "direct", "direction")
"""``task.approach`` values."""
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
    zero_check: bool = True
    """Read free space at every trial's end (the retract plane) before the trial counts: off
    zero by more than 3 sigma of what a fault-free check reads (the burst's and the zero's
    noise, the bias's drift since the zero), the zero moved during the trial, which is then void
    and runs again after a zero in free space; within it, the burst's mean becomes the zero
    (docs/on-site.md, "The zero check"). Costs a move to the retract plane (where a trial ends
    anyway) and a burst per trial; false: the paper's setup (zeroed once)."""
    press_stiffness_n_per_mm: float = 20.0
    """The stiffest part the cell may meet before it knows the part's stiffness (no probe yet,
    and no two readings in contact), N/mm (fast, unrelaxed): every move that presses in is cut
    so that this stiffness could not push the force past ``safety.max_force_n`` from the last
    reading (:mod:`forcelearn.press_guard`). After the probe its fits are used instead."""
    approach: str = "auto"
    """How each step reaches its Y (:data:`APPROACHES`): "loading" first stands a few branch
    depths shallower at the new Z, then presses in, so a hysteretic foam is read on its
    loading branch whichever way the learner moved; "direct" moves straight there (the
    paper's); "auto" approaches from the loading side when the probe resolved the foam's
    hysteresis (:mod:`forcelearn.tasks.surface_hysteresis`), else moves directly;
    "direction" moves directly and gives the learner the direction of the last move as a
    second input (2 boxes: pressed in, eased off; ``learner.extent`` then needs 2 entries),
    the design docs/results/materials.md compares with "loading"."""

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
        if self.approach not in APPROACHES:
            raise ConfigError(
                f"task.approach = {self.approach!r}: one of {', '.join(APPROACHES)} (\"loading\": "
                "press into each step from above, for a hysteretic foam; \"direct\": the paper's)"
            )
        if not isinstance(self.tare_each_trial, bool):
            raise ConfigError(f"task.tare_each_trial = {self.tare_each_trial!r}: true or false")
        if not isinstance(self.zero_check, bool):
            raise ConfigError(f"task.zero_check = {self.zero_check!r}: true or false")
        positive = ("desired_force_n", "tolerance_n", "output_scale_mm", "max_offset_mm",
                    "tare_max_reading_n", "press_stiffness_n_per_mm")
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
    def evaluation(self) -> ForceEvaluation:
        """The task's evaluation: r = |F − F_d| / :attr:`tolerance`, failure above 1."""
        return ForceEvaluation(self.desired_force_n, self.tolerance)

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
        """The BOXES partition of the distance travelled (one box per step by default).

        With ``approach = "direction"`` a second dimension: the last move's direction.
        """
        half = 0.5 * self.path_mm / self.input_parts
        travel = Dimension("travel_mm", -half, self.path_mm - half, self.input_parts)
        if self.approach == "direction":  # −1: the last move pressed in, +1: it eased off
            return BoxGrid([travel, Dimension("last_move", -2.0, 2.0, 2)])
        return BoxGrid([travel])

    def start_pose(self) -> Pose:
        """The pose each trial starts from."""
        return Pose(*self.start_mm, self.orientation or IDENTITY_QUATERNION)


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
