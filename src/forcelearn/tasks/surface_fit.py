"""What the surface probe reads and fits: its settings, its readings, the contact fit per point.

Fit (per point): relaxed force F = k · (y_c − y) by least squares over the
points in contact; stiffness k (N/mm) and contact Y y_c (mm), each with its
standard error from the residuals. :class:`ProbeResult` holds the readings and
the fits and interpolates them in Z: the surface model the output map
(:mod:`forcelearn.tasks.surface_map`) and the warm start use.
:class:`~forcelearn.tasks.surface_probe.SurfaceProbe` takes the readings.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any, TypedDict, cast

import numpy as np

from forcelearn.errors import ConfigError, ForcelearnError
from forcelearn.tasks.surface_hysteresis import HysteresisFit, fit_hysteresis
from forcelearn.tasks.surface_spec import SurfaceTaskSpec

log = logging.getLogger(__name__)

FOLLOW_MODES = ("auto", "always", "never")


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
    """Step of the approach from the retract plane towards the surface, mm; finer on a stiff
    part where one step passes a third of the press (:mod:`forcelearn.tasks.approach`)."""
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
    ease_off_mm: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0, 4.0)
    """After its deepest press, the probe eases off by each of these (mm, at most 0.8 of
    the press's depth) and reads: the foam's unloading branch, its hysteresis
    (:mod:`forcelearn.tasks.surface_hysteresis`); empty: not measured."""
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
        if not (
            isinstance(self.ease_off_mm, tuple)
            and all(_finite(e) and 0.0 < e <= 50.0 for e in self.ease_off_mm)
        ):
            raise ConfigError(
                f"probe.ease_off_mm = {self.ease_off_mm!r}: distances in (0, 50] mm, or empty"
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

    def limit_n(self, max_force_n: float) -> float:
        """The probe's own force limit under the cell's ``max_force_n``, N."""
        return self.max_force_ratio * max_force_n


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
        raise ProbeError(
            f"the probe at z = {z_mm:g} mm got {len(y)} readings in contact; need 2: on a stiff "
            "part with a small force one approach step already reaches the deepest press; set "
            "[probe] approach_step_mm below press_force_ratio x [task] desired_force_n / the "
            "part's stiffness (e.g. 0.25 mm for 8 N/mm at 5 N)")
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
    """Every reading: point, z_mm, y_mm, phase ("baseline", "approach", "refine": a first
    contact met in too coarse a step, approached again finer (:mod:`forcelearn.tasks.approach`),
    "press", "ease": eased off after the deepest press), force_n (relaxed, baseline removed),
    early_force_n, cell_time_s."""
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

    def hysteresis(self) -> HysteresisFit:
        """The foam's hysteresis from the eased-off readings of every point.

        Each "ease" reading against the loading force at its Y (that point's
        press readings, interpolated in Y); the noise floor is the spread of the
        free-space baselines (:func:`~forcelearn.tasks.surface_hysteresis.fit_hysteresis`).
        """
        ease, unloaded, loaded = [], [], []
        for point in sorted({r["point"] for r in self.rows}):
            press = sorted((r["y_mm"], r["force_n"]) for r in self.rows
                           if r["point"] == point and r["phase"] == "press")
            if len(press) < 2:
                continue
            ys, fs = np.array([p[0] for p in press]), np.array([p[1] for p in press])
            for row in self.rows:
                if row["point"] == point and row["phase"] == "ease" and row["y_mm"] <= ys[-1]:
                    ease.append(row["y_mm"] - ys[0])
                    unloaded.append(row["force_n"])
                    loaded.append(float(np.interp(row["y_mm"], ys, fs)))
        noise = float(np.std(self.baselines_n)) if len(self.baselines_n) > 1 else 0.0
        return fit_hysteresis(np.array(ease), np.array(unloaded), np.array(loaded), noise)

    def correct_drift(self) -> tuple[float, float]:
        """Bring every fit to the foam as the last one found it; return (contact shift mm, k ratio).

        The last fit re-probed the first one's Z: every point the probe pressed is a
        pass over the foam, which sinks (set) and softens with passes, so a long
        (dense) probe's early points describe a surface the task no longer meets.
        Every fit at the first one's Z is a reading of the drift at its place in
        the probing order; between them the drift is interpolated linearly in that
        order, and each fit moves by the drift still to come after it (the last
        one's less its own). With only the first and the last at that Z, fit i of
        n moves by (1 − i / (n − 1)) of the whole drift. A re-probe in the middle
        follows a set that slows with the passes (the emulated foam's: a straight
        line through the two ends alone over-corrects the middle fits by up to
        0.03 mm, a band at 8 N/mm and 5 N). The readings (rows) stay as read.
        """
        first, last = self.fits[0], self.fits[-1]
        shift = last.contact_y_mm - first.contact_y_mm
        ratio = last.stiffness_n_per_mm / first.stiffness_n_per_mm
        count = len(self.fits) - 1
        if count <= 0:
            return shift, ratio
        marks = [i for i, f in enumerate(self.fits) if f.z_mm == first.z_mm]
        if marks[-1] != count:
            marks.append(count)  # the last fit is the re-probe whatever its Z reads
        at = np.arange(count + 1, dtype=float)
        sunk = np.interp(at, marks, [self.fits[i].contact_y_mm - first.contact_y_mm
                                     for i in marks])
        soft = np.interp(at, marks, [math.log(self.fits[i].stiffness_n_per_mm
                                              / first.stiffness_n_per_mm) for i in marks])
        self.fits = [
            replace(f, contact_y_mm=f.contact_y_mm + shift - float(sunk[i]),
                    stiffness_n_per_mm=f.stiffness_n_per_mm * ratio / math.exp(float(soft[i])))
            for i, f in enumerate(self.fits)
        ]
        return shift, ratio

    def stiffness_n_per_mm(self) -> float:
        """Mean fitted stiffness over the points, N/mm."""
        return float(np.mean([f.stiffness_n_per_mm for f in self.fits]))

    def target_path_mm(self, task: SurfaceTaskSpec, force_n: float | None = None) -> np.ndarray:
        """Y (mm) where each step's fit gives ``force_n`` (default the desired force), per step.

        The fits' target Y = contact Y − force / stiffness, interpolated
        linearly in Z between the probed points (held beyond them): the surface
        model a force-control engineer would feed forward.
        """
        z_steps = task.start_mm[2] + task.z_step_mm * np.arange(1, task.steps_per_trial + 1)
        return self._targets_at(task, z_steps, force_n)

    def free_space_reading_n(self) -> float:
        """The sensor's reading in free space at the probe's last point, N (0: none read).

        The fits' forces are each point's readings less its own free-space
        baseline; the task's readings are not: they carry the sensor's bias as it
        has drifted since it was zeroed, best known from the latest baseline.
        """
        return float(self.baselines_n[-1]) if self.baselines_n else 0.0

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

    def _targets_at(
        self, task: SurfaceTaskSpec, z_mm: np.ndarray, force_n: float | None = None
    ) -> np.ndarray:
        if not self.fits:
            raise ProbeError("the probe fitted no point")
        force = task.desired_force_n if force_n is None else force_n
        by_z: dict[float, list[float]] = {}
        for f in self.fits:  # a point probed twice: the mean of its targets
            by_z.setdefault(f.z_mm, []).append(f.target_y_mm(force))
        z_fit = np.array(sorted(by_z))
        y_fit = np.array([float(np.mean(by_z[z])) for z in z_fit])
        if len(z_fit) == 1:
            return np.full(len(z_mm), float(y_fit[0]))
        return np.asarray(np.interp(z_mm, z_fit, y_fit), dtype=float)
