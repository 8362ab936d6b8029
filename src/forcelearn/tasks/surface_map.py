"""The §5 output map: the Y command of every action, and how the probe's fits choose it.

The learner's action a becomes the Y command y = centre + scale · a within
±half-range (:class:`SurfaceYOutput`, mm). Centre, scale and half-range come
from the surface probe (:func:`choose_output_map`) unless the config gives
them (``task.output_centre_y_mm``, ``output_scale_mm``, ``max_offset_mm``);
with no probe and no config, the fallback is start Y, 2 mm and 15 mm
(:func:`configured_map`).

Chosen from the probe: centre = mean over the points of the Y where the fit
gives the desired force; scale = ``force_per_unit`` × tolerance / k (so one
action unit is the same share of the tolerance on any sponge; 2 mm on the
default one); half-range = the spread of those Ys + 3 mm + ``wear_margin`` ×
the needed depth (the sponge softens and sets with wear; the desired force
drifts deeper). The range is cut to the allowed depth (``max_depth_mm`` below
the shallowest contact, and the workspace) and kept under the retract plane.
A desired force whose needed depth (with 10 % margin) passes the allowed depth
is refused (:class:`~forcelearn.tasks.surface_fit.ProbeError`, with both figures).

Following the surface (``follow_surface``): where the fits say a constant
centre would put the force outside the tolerance somewhere along the path
(:func:`constant_centre_error_ratio`: the largest k_i · |y_i − centre| over
the points passes 0.8 of the tolerance: a stiff sponge or a small force,
where the tolerance is a fraction of a millimetre or the sponge's wear a
large part of it), the probe adds ``refine_points`` and the centre becomes a
path: per step, the Y where the fits, interpolated in Z, give the desired
force. The half-range is then 3 mm + ``wear_margin`` × the needed depth around
it, and each trial's start press goes to the path's Y at the start Z (not
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
force towards the range's deep end. And when the learner's μ drift past half
the range, the range re-centres on them (:meth:`SurfaceYOutput.recentre_on`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from forcelearn.tasks.surface_fit import ProbeError, ProbeResult, ProbeSpec
from forcelearn.tasks.surface_hysteresis import NOT_FITTED, HysteresisFit
from forcelearn.tasks.surface_spec import SurfaceTaskSpec
from forcelearn.trainer import CONVERGENCE_TOLERANCE

log = logging.getLogger(__name__)

DENSE_ABOVE = 2.0
"""The probe measures every step's Z once an interval's own interpolation error, in force,
passes this many bands (:func:`dense_points`). The estimate is pessimistic (the default
cell's largest is 0.6 N, 0.6 band, and its warm start is in band from trial 0): 2 bands
leave the default cell and a 3 N/mm foam at 2 kgf at 7 points and densify a 6 N/mm foam
with 3 mm waves at 0.75 kgf (about 2 N, 5 bands)."""

APPROACH_DEPTHS = 4.0
"""A step approached from the loading side starts this many branch depths above its command."""
DEFAULT_BRANCH_DEPTH_MM = 0.5
"""Branch depth assumed when the probe did not fit one (the emulated foam's default), mm."""
APPROACH_DEPTH_SHARE = 0.5
"""The approach from the loading side stays within this share of the shallowest depth the
desired force needs: the roller stays on the foam (off it, every step would be a pass that
wears the foam, and its press a fresh indentation that reads its unrelaxed force)."""
MIN_APPROACH_MM = 0.5
"""Shortest approach from the loading side, mm."""
MAX_APPROACH_MM = 5.0
"""Longest approach from the loading side, mm."""

MIN_MARGIN_MM = 3.0
"""Least margin of the output range beyond the spread of the target Ys, mm."""
NEEDED_DEPTH_MARGIN = 1.1
"""A desired force is refused when 1.1 × its needed depth passes the allowed depth."""
FOLLOW_ABOVE = 0.8
"""``auto`` follows the surface when the predicted error of a constant centre passes
this × the tolerance at some probed point. The default cell is at 0.58 and keeps
the paper's constant centre; at 0.83-0.96 (1 N/mm at 0.5 kgf) a constant centre
converged but ended one seed in three at 8 % force RMS (docs/results/surface.md)."""
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
        approach_mm: float = 0.0,
    ):
        self.start_y_mm = start_y_mm
        """The centre Y (mm): the command at action 0 (the mean centre with a path)."""
        self.approach_mm = approach_mm
        """Each step first stands this much shallower (mm), then presses to its command
        (0: straight there; :func:`approach_depth_mm`)."""
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
    approach_mm: float = 0.0
    """Each step presses in from this much shallower, so the foam answers on its loading
    branch (mm; 0: straight to the command; :func:`approach_depth_mm`)."""

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
            approach_mm=self.approach_mm,
        )

    def centre_at(self, step_index: int) -> float:
        """The centre Y (mm) of step ``step_index`` (0: the first step of a trial)."""
        return step_centre_y_mm(self.path_y_mm, self.centre_y_mm, step_index)

    @property
    def action_range(self) -> float:
        """Half-range in action units."""
        return self.max_offset_mm / self.scale_mm


def constant_centre_error_ratio(result: ProbeResult, task: SurfaceTaskSpec) -> float:
    """Largest predicted |force error| of a constant centre at the probed points, in tolerances.

    At point i the force at the centre c is F + k_i (t_i − c) (t_i: where the fit
    gives the desired force F), so its error is k_i |t_i − c|.
    """
    targets = np.array([f.target_y_mm(task.desired_force_n) for f in result.fits])
    ks = np.array([f.stiffness_n_per_mm for f in result.fits])
    return task.evaluation.ratio(float(np.max(ks * np.abs(targets - np.mean(targets)))))


def dense_points(result: ProbeResult, task: SurfaceTaskSpec) -> tuple[float, ...]:
    """Where the probe must add points, as fractions of the path: the steps it does not resolve.

    Each inner probed Z's target Y is predicted from its two neighbours; a
    quarter of the miss is what the probed grid itself misses between its
    points (an interpolation error falls with the square of the spacing). Where
    that, times the stiffness, passes ``DENSE_ABOVE`` bands (5 % of the
    desired force) at any point, every step's Z not yet probed is returned: a
    stiff part at a small force, whose position band (band / k) is a fraction
    of the surface's waves, gets its surface measured where the task steps,
    not interpolated. Every step's, not only those between the flagged
    point's neighbours: a three-point check sees a wave's crest near the
    path's ends (or between unevenly spaced points) at a fraction of its
    curvature (the emulated sponge at 8 N/mm, 5 N: 0.4 N estimated at -12.5 mm
    where steps 1-2 missed by 0.8 and 0.5 N), so a grid found too coarse for
    the band at one point is taken as too coarse along the whole path.
    """
    by_z: dict[float, list[tuple[float, float]]] = {}
    for f in result.fits:
        by_z.setdefault(f.z_mm, []).append((f.target_y_mm(task.desired_force_n),
                                            f.stiffness_n_per_mm))
    z = np.array(sorted(by_z))
    if len(z) < 3:
        return ()
    target = np.array([np.mean([t for t, _ in by_z[v]]) for v in z])
    k = np.array([np.mean([s for _, s in by_z[v]]) for v in z])
    band = CONVERGENCE_TOLERANCE * task.desired_force_n
    steps = np.arange(1, task.steps_per_trial + 1)
    step_z = task.start_mm[2] + task.z_step_mm * steps
    wanted: set[int] = set()
    for i in range(1, len(z) - 1):
        between = np.interp(z[i], [z[i - 1], z[i + 1]], [target[i - 1], target[i + 1]])
        if k[i] * abs(float(target[i] - between)) / 4.0 > DENSE_ABOVE * band:
            wanted.update(int(s) for s in steps)
            break
    probed = {round(float(v), 6) for v in z}
    return tuple(s / task.steps_per_trial for s in sorted(wanted)
                 if round(float(step_z[s - 1]), 6) not in probed)


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
        min(approach_depth_mm(task, result.hysteresis()),
            APPROACH_DEPTH_SHARE * float(np.min(depths))),
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
        approach_mm=approach_depth_mm(task, NOT_FITTED),
    )


def approach_depth_mm(task: SurfaceTaskSpec, hysteresis: HysteresisFit) -> float:
    """How far above its command each step starts its press, mm (``task.approach``).

    ``APPROACH_DEPTHS`` branch depths (the fit's d_h plus two standard errors,
    else ``DEFAULT_BRANCH_DEPTH_MM``), within ``MIN_APPROACH_MM``..``MAX_APPROACH_MM``:
    after a press of four d_h the foam's branch state is within 2 e^-4 (4 %) of
    loading whatever it was, so the force read varies by < 0.04 h of the elastic
    one. "auto" approaches only when the probe resolved the hysteresis.
    """
    if task.approach in ("direct", "direction") or (
        task.approach == "auto" and not hysteresis.resolved
    ):
        return 0.0
    depth = hysteresis.depth_mm + 2.0 * hysteresis.depth_std
    if not math.isfinite(depth):
        depth = DEFAULT_BRANCH_DEPTH_MM
    return min(max(APPROACH_DEPTHS * depth, MIN_APPROACH_MM), MAX_APPROACH_MM)
