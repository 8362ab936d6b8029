"""Find the surface before learning: a short, force-guarded probe, a fit, and the output map.

At a few points along the §5 path (``[probe] points``: fractions of the path,
default its start, middle and end) the probe

1. stands off at the retract plane (``task.retract_y_mm``) and reads the
   free-space force (the baseline);
2. approaches along −Y in steps of ``approach_step_mm`` until the force rises
   ``contact_force_n`` above the baseline (no further than ``max_depth_mm``
   below the retract plane and never outside the workspace);
3. presses on in ``press_points`` steps, sized from a running stiffness
   estimate so the last one reaches about ``press_force_ratio`` × the desired
   force; after each step it **dwells** ``dwell_s`` before it reads the force:
   a fresh indentation of foam reads stiffer (the standard linear solid of the
   emulated sponge reads ~25 % high at first and relaxes with 0.4 s), and the
   dwell of ~4 time constants leaves < 1 % of that, so the fit is of the
   relaxed stiffness, the one a slow pass sees. The force right after the
   step is kept too (``early_force_n``) to show the relaxation;
4. retracts to the retract plane.

Every step is force-guarded: one move at a time, the force read after every
move through :meth:`Cell.measure_force_n` (which stops the robot past
``safety.max_force_n``), and the probe itself stops pressing before a step
whose predicted (unrelaxed) force would pass ``max_force_ratio`` × the limit.

Fit (per point): relaxed force F = k · (y_c − y) by least squares over the
points in contact; stiffness k (N/mm) and contact Y y_c (mm), each with its
standard error from the residuals.

Output map (what the learner commands, y = centre + scale · a within
±half-range): centre = mean over the points of the Y where the fit gives the
desired force; scale = ``force_per_unit`` × tolerance / k (so one action unit
is the same share of the tolerance on any sponge; 2 mm on the default one);
half-range = the spread of those Ys + 3 mm + ``wear_margin`` × the needed
depth (the sponge softens and sets with wear; the desired force drifts
deeper). The range is cut to the allowed depth (``max_depth_mm`` below the
shallowest contact, and the workspace) and kept under the retract plane.
A desired force whose needed depth (with 10 % margin) passes the allowed depth
is refused (:class:`ProbeError`, with both figures).

Following the surface (``follow_surface``): where the fits say a constant
centre would put the force outside the tolerance somewhere along the path
(the largest k_i · |y_i − centre| over the points passes 0.8 of the
tolerance: a stiff sponge or a small force, where the tolerance is a
fraction of a millimetre or the sponge's wear a large part of it), the
probe adds ``refine_points`` and the centre becomes a path:
per step, the Y where the fits, interpolated in Z, give the desired force.
The half-range is then 3 mm + ``wear_margin`` × the needed depth around it,
and each trial's start press goes to the path's Y at the start Z (not
``start_mm``'s Y, which on a stiff sponge presses several times the desired
force). On the default cell a constant centre stays (the paper's task).

Following the wear (every map the probe chose, constant or path): each
trial's start press is the same press with the same settle, so its force
against the first trial's says how far the surface has sunk or softened, and
the whole map (centres and start press) shifts by half that depth per trial
(:meth:`SurfaceYOutput.track_wear`, with the probe's stiffness), within
``shift_range_mm``: as far as the range stays between the deepest allowed Y
and 1 mm under the retract plane. On a stiff sponge at a small force the
wear's 2 mm of set is several tolerances, more than the learner's
specialized phase follows; on a soft one the softening takes the desired
force towards the range's deep end.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field
from typing import Any, TypedDict, cast

import numpy as np

from forcelearn.cell import Cell
from forcelearn.devices import Pose
from forcelearn.errors import ConfigError, ForcelearnError
from forcelearn.tasks.surface import SurfaceTaskSpec, SurfaceYOutput, step_centre_y_mm

log = logging.getLogger(__name__)

MIN_MARGIN_MM = 3.0
"""Least margin of the output range beyond the spread of the target Ys, mm."""
NEEDED_DEPTH_MARGIN = 1.1
"""A desired force is refused when 1.1 × its needed depth passes the allowed depth."""
FOLLOW_MODES = ("auto", "always", "never")
FOLLOW_ABOVE = 0.8
"""``auto`` follows the surface when the predicted error of a constant centre passes
this × the tolerance at some probed point. The default cell is at 0.58 and keeps
the paper's constant centre; at 0.83-0.96 (1 N/mm at 0.5 kgf) a constant centre
converged but ended one seed in three at 8 % force RMS (docs/results/surface.md)."""


class ProbeError(ForcelearnError):
    """The probe found no surface, or a surface on which the desired force cannot be reached."""


def _finite(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class ProbeSpec:
    """The probe's settings (``[probe]`` table); lengths mm, forces N, times s (robot clock)."""

    enabled: bool = True
    """Probe at the start of a new run (the output map then comes from it)."""
    points: tuple[float, ...] = (0.0, 0.5, 1.0)
    """Where along the path to probe, as fractions of it (0: start Z, 1: end Z)."""
    approach_step_mm: float = 1.0
    """Step of the approach from the retract plane towards the surface, mm."""
    contact_force_n: float = 1.0
    """Rise of the force above the free-space baseline that marks contact, N."""
    press_points: int = 6
    """Force readings in contact per point (the first contact counts), >= 3."""
    press_force_ratio: float = 1.25
    """The deepest press aims at this × the desired force (the fit spans the working force)."""
    max_force_ratio: float = 0.7
    """The probe never steps where its predicted unrelaxed force passes this × the force limit."""
    max_depth_mm: float = 38.0
    """Deepest compression allowed below the contact, mm (assumption: 95 % of the default
    40 mm foam; set it from your material: beyond it the roller meets the backing)."""
    dwell_s: float = 1.5
    """Wait after each press step before reading, s (~4 relaxation time constants of the foam)."""
    samples: int = 16
    """Sensor samples read per force reading."""
    force_per_unit: float = 0.4
    """One action unit = this share of the tolerance in force (sets the scale)."""
    wear_margin: float = 0.5
    """Extra half-range for wear and drift, as a share of the needed depth."""
    follow_surface: str = "auto"
    """The map's centre along the path: "auto" (follow the fitted surface where a
    constant centre would leave the tolerance), "always" or "never"."""
    refine_points: tuple[float, ...] = (0.125, 0.375, 0.625, 0.875)
    """Points probed in addition before following the surface (its waves are
    shorter than the path), fractions of the path."""

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"probe.enabled = {self.enabled!r}: true or false")
        if not (
            isinstance(self.points, tuple)
            and self.points
            and all(_finite(p) and 0.0 <= p <= 1.0 for p in self.points)
        ):
            raise ConfigError(f"probe.points = {self.points!r}: fractions of the path in [0, 1]")
        if not (
            isinstance(self.refine_points, tuple)
            and all(_finite(p) and 0.0 <= p <= 1.0 for p in self.refine_points)
        ):
            raise ConfigError(
                f"probe.refine_points = {self.refine_points!r}: fractions of the path in [0, 1]"
            )
        if self.follow_surface not in FOLLOW_MODES:
            raise ConfigError(
                f"probe.follow_surface = {self.follow_surface!r}: one of {', '.join(FOLLOW_MODES)}"
            )
        for name in ("press_points", "samples"):
            value = getattr(self, name)
            least = 3 if name == "press_points" else 1
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ConfigError(f"probe.{name} = {value!r}: a whole number >= {least}")
        positive = (
            "approach_step_mm", "contact_force_n", "press_force_ratio", "max_depth_mm",
            "force_per_unit",
        )
        for name in positive:
            value = getattr(self, name)
            if not (_finite(value) and value > 0):
                raise ConfigError(f"probe.{name} = {value!r}: a finite number > 0")
        for name in ("dwell_s", "wear_margin"):
            value = getattr(self, name)
            if not (_finite(value) and value >= 0):
                raise ConfigError(f"probe.{name} = {value!r}: a finite number >= 0")
        if not (_finite(self.max_force_ratio) and 0 < self.max_force_ratio < 1):
            raise ConfigError(f"probe.max_force_ratio = {self.max_force_ratio!r}: in (0, 1)")


@dataclass(frozen=True)
class ContactFit:
    """F = k · (y_c − y) fitted at one probe point."""

    z_mm: float
    stiffness_n_per_mm: float
    stiffness_std: float
    contact_y_mm: float
    contact_y_std: float
    residual_rms_n: float
    points: int

    def target_y_mm(self, force_n: float) -> float:
        """The Y (mm) where this fit gives ``force_n``."""
        return self.contact_y_mm - force_n / self.stiffness_n_per_mm


def fit_contact(y_mm: np.ndarray, force_n: np.ndarray, z_mm: float = math.nan) -> ContactFit:
    """Least-squares F = k (y_c − y) through readings in contact; standard errors from residuals.

    Raises:
        ProbeError: fewer than 2 readings, or no force rise with depth.
    """
    y = np.asarray(y_mm, float)
    f = np.asarray(force_n, float)
    if len(y) < 2:
        raise ProbeError(f"the probe at z = {z_mm:g} mm got {len(y)} readings in contact; need 2")
    design = np.column_stack([np.ones_like(y), y])
    coef, *_ = np.linalg.lstsq(design, f, rcond=None)
    intercept, slope = float(coef[0]), float(coef[1])
    if not slope < 0:
        raise ProbeError(
            f"the force did not rise with depth at z = {z_mm:g} mm (slope {-slope:.3g} N/mm): "
            "is the sensor's normal axis/sign right ([filter] axis, sign)?"
        )
    residual = f - design @ coef
    dof = max(len(y) - 2, 1)
    s2 = float(residual @ residual) / dof
    cov = s2 * np.linalg.pinv(design.T @ design)
    k = -slope
    y_c = intercept / k
    # y_c = -a/b: gradient (-1/b, a/b^2)
    grad = np.array([-1.0 / slope, intercept / slope**2])
    y_c_var = float(grad @ cov @ grad)
    return ContactFit(
        z_mm=float(z_mm),
        stiffness_n_per_mm=k,
        stiffness_std=math.sqrt(max(float(cov[1, 1]), 0.0)),
        contact_y_mm=y_c,
        contact_y_std=math.sqrt(max(y_c_var, 0.0)),
        residual_rms_n=math.sqrt(float(residual @ residual) / len(y)),
        points=len(y),
    )


@dataclass(frozen=True)
class OutputMapChoice:
    """The output map y = centre + scale · a within ±max_offset (mm), and where it came from."""

    centre_y_mm: float
    scale_mm: float
    max_offset_mm: float
    needed_depth_mm: float
    """Mean compression (mm) the fits predict for the desired force."""
    allowed_depth_mm: float
    """Deepest compression below the shallowest contact the map may command, mm."""
    source: str = "probe"
    """"probe", "config" or "probe+config" (keys given in the config win)."""
    path_y_mm: tuple[float, ...] = ()
    """Following the surface: the centre Y of each step (mm); empty: ``centre_y_mm``."""
    start_press_y_mm: float | None = None
    """Following the surface: Y of each trial's start press (mm); None: ``task.start_mm``."""
    wear_stiffness_n_per_mm: float | None = None
    """The stiffness the map tracks wear with (the probe's; None: no tracking)."""
    shift_range_mm: tuple[float, float] | None = None
    """Following wear: the least and most shift (mm) that keep the whole range between
    the deepest allowed Y and 1 mm under the retract plane (None: no tracking)."""
    allowed_bottom_y_mm: float | None = None
    """The deepest Y allowed (mm): ``probe.max_depth_mm`` below the deepest probed contact,
    or the workspace floor (None: no probe, or a checkpoint from before it was kept)."""

    def __post_init__(self) -> None:  # JSON gives lists
        object.__setattr__(self, "path_y_mm", tuple(float(v) for v in self.path_y_mm))
        if self.shift_range_mm is not None:
            low, high = self.shift_range_mm
            object.__setattr__(self, "shift_range_mm", (float(low), float(high)))

    def output(self, step_mm: float = 5.0) -> SurfaceYOutput:
        """The learner's output function (``step_mm``: the task's Z step, mm)."""
        return SurfaceYOutput(
            self.centre_y_mm, self.scale_mm, self.max_offset_mm, self.path_y_mm, step_mm,
            self.start_press_y_mm, self.wear_stiffness_n_per_mm, self.shift_range_mm,
        )

    def centre_at(self, step_index: int) -> float:
        """The centre Y (mm) of step ``step_index`` (0: the first step of a trial)."""
        return step_centre_y_mm(self.path_y_mm, self.centre_y_mm, step_index)

    @property
    def action_range(self) -> float:
        """Half-range in action units."""
        return self.max_offset_mm / self.scale_mm


class ProbeRow(TypedDict):
    """One reading of the probe (a row of probe.csv)."""

    point: int
    z_mm: float
    y_mm: float
    phase: str
    early_force_n: float
    force_n: float
    cell_time_s: float


@dataclass
class ProbeResult:
    """What the probe read and fitted (JSON-able through :meth:`to_json`)."""

    rows: list[ProbeRow] = field(default_factory=list)
    """Every reading: point, z_mm, y_mm, phase ("baseline", "approach", "press"),
    force_n (relaxed, baseline removed), early_force_n, cell_time_s."""
    fits: list[ContactFit] = field(default_factory=list)
    baselines_n: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """Plain data for a checkpoint or summary.json."""
        return {
            "rows": self.rows,
            "fits": [asdict(f) for f in self.fits],
            "baselines_n": self.baselines_n,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ProbeResult:
        """Inverse of :meth:`to_json`."""
        return cls(
            rows=[cast(ProbeRow, dict(r)) for r in data["rows"]],  # as to_json wrote them
            fits=[ContactFit(**f) for f in data["fits"]],
            baselines_n=[float(b) for b in data["baselines_n"]],
        )

    def stiffness_n_per_mm(self) -> float:
        """Mean fitted stiffness over the points, N/mm."""
        return float(np.mean([f.stiffness_n_per_mm for f in self.fits]))

    def target_path_mm(self, task: SurfaceTaskSpec) -> np.ndarray:
        """Y (mm) where each step's fit gives the desired force, one per step of a trial.

        The fits' target Y = contact Y − desired force / stiffness, interpolated
        linearly in Z between the probed points (held beyond them): the surface
        model a force-control engineer would feed forward.
        """
        z_steps = task.start_mm[2] + task.z_step_mm * np.arange(1, task.steps_per_trial + 1)
        return self._targets_at(task, z_steps)

    def contact_path_mm(self, task: SurfaceTaskSpec) -> np.ndarray:
        """Contact Y (mm) of the fits at each step's Z, interpolated like :meth:`target_path_mm`."""
        z_steps = task.start_mm[2] + task.z_step_mm * np.arange(1, task.steps_per_trial + 1)
        by_z: dict[float, list[float]] = {}
        for f in self.fits:
            by_z.setdefault(f.z_mm, []).append(f.contact_y_mm)
        z_fit = np.array(sorted(by_z))
        y_fit = np.array([float(np.mean(by_z[z])) for z in z_fit])
        return np.asarray(np.interp(z_steps, z_fit, y_fit), dtype=float)

    def target_at_z_mm(self, task: SurfaceTaskSpec, z_mm: float) -> float:
        """Y (mm) where the fits, interpolated in Z, give the desired force at ``z_mm``."""
        return float(self._targets_at(task, np.array([z_mm]))[0])

    def _targets_at(self, task: SurfaceTaskSpec, z_mm: np.ndarray) -> np.ndarray:
        if not self.fits:
            raise ProbeError("the probe fitted no point")
        by_z: dict[float, list[float]] = {}
        for f in self.fits:  # a point probed twice: the mean of its targets
            by_z.setdefault(f.z_mm, []).append(f.target_y_mm(task.desired_force_n))
        z_fit = np.array(sorted(by_z))
        y_fit = np.array([float(np.mean(by_z[z])) for z in z_fit])
        if len(z_fit) == 1:
            return np.full(len(z_mm), float(y_fit[0]))
        return np.asarray(np.interp(z_mm, z_fit, y_fit), dtype=float)


class SurfaceProbe:
    """Runs the probe on a cell (see the module docstring); one instance per probe."""

    def __init__(
        self,
        cell: Cell,
        task: SurfaceTaskSpec,
        spec: ProbeSpec,
        max_step_mm: float,
        workspace_min_y_mm: float,
    ):
        self.cell = cell
        self.task = task
        self.spec = spec
        self.max_step_mm = max_step_mm
        self.floor_y_mm = workspace_min_y_mm
        self.result = ProbeResult()
        self._next_index = 0

    def run(self, points: tuple[float, ...] | None = None) -> ProbeResult:
        """Probe ``points`` (default ``spec.points``); the robot ends at the retract plane.

        A second call adds its points to the same result (numbered on).
        """
        x, _, z0 = self.task.start_mm
        for fraction in self.spec.points if points is None else points:
            z = z0 + fraction * self.task.steps_per_trial * self.task.z_step_mm
            try:
                self._probe_point(self._next_index, x, z)
            finally:
                self._next_index += 1
                self._retract()
        return self.result

    def _pose(self, x: float, y: float, z: float) -> Pose:
        return Pose(x, y, z, self.task.start_pose().quaternion)

    def _retract(self) -> None:
        pose = self.cell.pose
        self.cell.move_in_steps(
            self._pose(pose.x_mm, self.task.retract_y_mm, pose.z_mm), self.max_step_mm
        )

    def _read(self, dwell_s: float) -> tuple[float, float]:
        """(early, relaxed) force, N: read at once, then again after ``dwell_s``."""
        cell = self.cell
        cell.reset_filter()
        early = cell.measure_force_n(self.spec.samples)
        if dwell_s > 0:
            try:
                cell.time_s = cell.robot.wait_in_position(cell.move_timeout_s, dwell_s)
            except ForcelearnError:
                cell.stop()
                raise
        cell.reset_filter()
        return early, cell.measure_force_n(self.spec.samples)

    def _record(
        self, point: int, z: float, y: float, phase: str, early: float, force: float
    ) -> None:
        self.result.rows.append(
            {
                "point": point,
                "z_mm": z,
                "y_mm": y,
                "phase": phase,
                "early_force_n": early,
                "force_n": force,
                "cell_time_s": self.cell.time_s,
            }
        )

    def _probe_point(self, index: int, x: float, z: float) -> None:
        spec, task, cell = self.spec, self.task, self.cell
        cell.stage = ("probe", index)
        limit_n = spec.max_force_ratio * cell.max_force_n
        aim_n = min(spec.press_force_ratio * task.desired_force_n, limit_n / 1.4)
        top = task.retract_y_mm
        floor = max(self.floor_y_mm, top - spec.max_depth_mm - 60.0)
        self._retract()
        cell.move_in_steps(self._pose(x, top, z), self.max_step_mm)
        _, baseline = self._read(0.0)
        self.result.baselines_n.append(baseline)
        self._record(index, z, top, "baseline", baseline, 0.0)
        if baseline > spec.contact_force_n:
            raise ProbeError(
                f"force {baseline:.2f} N at the retract plane (task.retract_y_mm = {top:g} mm, "
                f"z = {z:g} mm): the tool is already in contact; raise task.retract_y_mm. "
                "If nothing touches it, the sensor reads a bias: zero it in free space "
                "(sensor.zero_on_init = true, or a calibration file)"
            )
        y = top
        while True:  # approach
            y -= spec.approach_step_mm
            if y < floor:
                raise ProbeError(
                    f"no contact between y = {top:g} and {floor:g} mm at z = {z:g} mm "
                    f"(force stayed under {spec.contact_force_n:g} N above the baseline): "
                    "check task.start_mm and task.retract_y_mm against where the surface is, "
                    "and [filter] axis and sign (the normal force is the sensor's component "
                    "axis times sign)"
                )
            cell.move_in_steps(self._pose(x, y, z), self.max_step_mm, guard_force=True)
            early = cell.measure_force_n() - baseline
            if early > spec.contact_force_n:
                break
            self._record(index, z, y, "approach", early, early)
        ys: list[float] = []
        forces: list[float] = []
        contact_guess = y + spec.approach_step_mm
        depth_floor = max(floor, contact_guess - spec.max_depth_mm)
        while True:  # press
            early, relaxed = self._read(spec.dwell_s)
            early, relaxed = early - baseline, relaxed - baseline
            self._record(index, z, y, "press", early, relaxed)
            ys.append(y)
            forces.append(relaxed)
            if len(ys) >= spec.press_points or relaxed >= aim_n:
                break
            if len(ys) >= 2:
                k = max((forces[0] - forces[-1]) / (ys[-1] - ys[0]), 1e-3)
            else:
                k = max(relaxed / max(contact_guess - y, 0.5 * spec.approach_step_mm), 1e-3)
            remaining = spec.press_points - len(ys)
            step = max((aim_n - relaxed) / k / remaining, 0.25 * spec.approach_step_mm)
            step = min(step, 0.99 * self.max_step_mm)
            seen = [(e - f) / f for e, f in zip(self._early(index), forces, strict=True) if f > 0.5]
            ratio = max(1.3, 1.0 + max(seen, default=0.0))  # unrelaxed / relaxed force
            if ratio * (relaxed + k * step) > limit_n or y - step < depth_floor:
                break  # the next step could pass the probe's force limit or depth
            y -= step
            cell.move_in_steps(self._pose(x, y, z), self.max_step_mm, guard_force=True)
        contact = [(yy, ff) for yy, ff in zip(ys, forces, strict=True) if ff > spec.contact_force_n]
        if len(contact) < 2:
            contact = list(zip(ys, forces, strict=True))
        fit = fit_contact(np.array([c[0] for c in contact]), np.array([c[1] for c in contact]), z)
        self.result.fits.append(fit)
        log.info(
            "probe z = %.1f mm: k = %.3f ± %.3f N/mm, contact y = %.2f ± %.2f mm (%d points)",
            z, fit.stiffness_n_per_mm, fit.stiffness_std, fit.contact_y_mm, fit.contact_y_std,
            fit.points,
        )

    def _early(self, index: int) -> list[float]:
        return [
            r["early_force_n"] for r in self.result.rows
            if r["point"] == index and r["phase"] == "press"
        ]


def constant_centre_error_ratio(result: ProbeResult, task: SurfaceTaskSpec) -> float:
    """Largest predicted |force error| of a constant centre at the probed points, in tolerances.

    At point i the force at the centre c is F + k_i (t_i − c) (t_i: where the fit
    gives the desired force F), so its error is k_i |t_i − c|.
    """
    targets = np.array([f.target_y_mm(task.desired_force_n) for f in result.fits])
    ks = np.array([f.stiffness_n_per_mm for f in result.fits])
    return float(np.max(ks * np.abs(targets - np.mean(targets)))) / task.tolerance


def choose_output_map(
    result: ProbeResult,
    task: SurfaceTaskSpec,
    spec: ProbeSpec,
    workspace_min_y_mm: float,
    follow: bool = False,
) -> OutputMapChoice:
    """Choose centre, scale and half-range from the fits; configured keys win.

    ``follow``: the centre is the fitted surface's path, one Y per step, and
    each trial's start press goes to the path's Y at the start Z (module doc).

    Raises:
        ProbeError: the desired force needs more depth than allowed (figures given).
    """
    fits = result.fits
    if not fits:
        raise ProbeError("the probe fitted no point")
    targets = np.array([f.target_y_mm(task.desired_force_n) for f in fits])
    depths = np.array([task.desired_force_n / f.stiffness_n_per_mm for f in fits])
    needed = float(np.max(depths))
    top_contact = max(f.contact_y_mm for f in fits)
    allowed_bottom = allowed_bottom_y_mm(result, spec, workspace_min_y_mm)
    allowed = top_contact - allowed_bottom
    if NEEDED_DEPTH_MARGIN * needed > allowed:
        raise ProbeError(
            f"task.desired_force_n = {task.desired_force_n:g} N needs {needed:.1f} mm of "
            f"compression (fitted stiffness {min(f.stiffness_n_per_mm for f in fits):.3g} N/mm, "
            f"with 10 % margin {NEEDED_DEPTH_MARGIN * needed:.1f} mm), more than the "
            f"{allowed:.1f} mm allowed (probe.max_depth_mm = {spec.max_depth_mm:g}, "
            "safety.workspace_min_mm): lower the desired force or allow more depth"
        )
    path: tuple[float, ...] = ()
    start_press: float | None = None
    if follow and task.output_centre_y_mm is None:
        path_array = result.target_path_mm(task)
        path = tuple(float(v) for v in path_array)
        start_press = result.target_at_z_mm(task, task.start_mm[2])
        centre = float(np.mean(path_array))
        half = MIN_MARGIN_MM + spec.wear_margin * float(np.mean(depths))
        half = min(half, float(np.min(path_array)) - allowed_bottom,
                   task.retract_y_mm - 1.0 - float(np.max(path_array)))
    else:
        centre = float(np.mean(targets))
        spread = float(np.max(np.abs(targets - centre)))
        half = spread + MIN_MARGIN_MM + spec.wear_margin * float(np.mean(depths))
        half = min(half, centre - allowed_bottom, task.retract_y_mm - 1.0 - centre)
    k = result.stiffness_n_per_mm()
    scale = spec.force_per_unit * task.tolerance / k
    source = "probe"
    if task.output_centre_y_mm is not None:
        centre, source = task.output_centre_y_mm, "probe+config"
    if task.output_scale_mm is not None:
        scale, source = task.output_scale_mm, "probe+config"
    if task.max_offset_mm is not None:
        half, source = task.max_offset_mm, "probe+config"
    if half <= 0:
        raise ProbeError(
            f"no room for an output range: centre y = {centre:.2f} mm, retract plane "
            f"task.retract_y_mm = {task.retract_y_mm:g} mm, deepest allowed y = "
            f"{allowed_bottom:.2f} mm"
        )
    # wear may move the map (and the start press) only as far as its range stays allowed
    lowest = min(path) if path else centre
    press = task.start_mm[1] if start_press is None else start_press
    highest = max((max(path) if path else centre) + half, press)
    shift_range = (
        min(0.0, allowed_bottom - (lowest - half)),
        max(0.0, task.retract_y_mm - 1.0 - highest),
    )
    return OutputMapChoice(
        centre, scale, half, needed, allowed, source, path, start_press, k, shift_range,
        allowed_bottom,
    )


def allowed_bottom_y_mm(
    result: ProbeResult, spec: ProbeSpec, workspace_min_y_mm: float
) -> float:
    """The deepest Y (mm) a map may command.

    ``probe.max_depth_mm`` below the deepest probed contact, or the workspace
    floor (``safety.workspace_min_mm``), whichever is higher.
    """
    return max(min(f.contact_y_mm for f in result.fits) - spec.max_depth_mm, workspace_min_y_mm)


def configured_map(task: SurfaceTaskSpec) -> OutputMapChoice:
    """The map without a probe: the configured keys, else the pre-probe fallback."""
    source = "config" if task.map_configured else "fallback"
    return OutputMapChoice(
        task.fallback_centre_y_mm,
        task.fallback_scale_mm,
        task.fallback_offset_mm,
        math.nan,
        math.nan,
        source,
    )



def probe_and_map(
    probe: SurfaceProbe, refine: bool = False
) -> tuple[ProbeResult | None, OutputMapChoice]:
    """Run ``probe`` (when enabled and the map is not all configured); choose the output map.

    Returns the probe's result (``None`` when it did not run; ``probe.result``
    holds what it read even when this raised) and the map. The native run and
    the Gymnasium env both start this way, so they learn on the same map.
    ``refine``: probe the ``refine_points`` too (the learner's warm start takes
    the probe's path, so the path's waves matter even under a constant centre).

    Raises:
        ProbeError: no surface found, or the desired force is out of reach.
    """
    task, spec = probe.task, probe.spec
    if not spec.enabled or task.map_configured:
        return None, configured_map(task)
    return map_from_probe(probe, refine)


def map_from_probe(
    probe: SurfaceProbe, refine: bool = False
) -> tuple[ProbeResult, OutputMapChoice]:
    """Run ``probe``, then its refinement when the map follows the surface (or ``refine``).

    ``forcelearn probe`` calls this directly (it probes even when the whole
    map is configured, whose keys then win).

    Raises:
        ProbeError: no surface found, or the desired force is out of reach.
    """
    task, spec = probe.task, probe.spec
    result = probe.run()
    follow = task.output_centre_y_mm is None and (
        spec.follow_surface == "always"
        or (spec.follow_surface == "auto"
            and constant_centre_error_ratio(result, task) > FOLLOW_ABOVE)
    )
    if follow or refine:
        log.info("probing %d more points (%s)", len(spec.refine_points),
                 "following the surface: a constant map centre would leave the tolerance "
                 "along the path" if follow else "the learner starts on the probe's path")
        probe.run(spec.refine_points)
    return result, choose_output_map(result, task, spec, probe.floor_y_mm, follow)
