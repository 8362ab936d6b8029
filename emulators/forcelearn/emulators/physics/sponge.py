"""The sponge of the paper's §5: a soft strip the roller presses along Y while moving down Z.

Description
-----------
A strip of foam occupies the half-space ``y <= surface_y(z)`` for
``z_bottom_mm <= z <= z_top_mm``. The roller at the tool centre point presses
into it along -Y; the sponge pushes back along its outward normal (mostly +Y).
Both the surface position and the stiffness vary along Z, the direction of
travel, so holding Y constant while stepping -5 mm in Z gives ramps and waves
in force, and the learner must learn a Y trajectory.

Rubbing changes the material: after ``n`` completed passes the stiffness is
scaled by ``1 - softening * (1 - exp(-n / softening_passes))`` and the surface
has sunk by a permanent set ``set_mm * (1 - exp(-n / set_passes))``. A trial
that starts from the same pose therefore meets a smaller initial contact
force as passes accumulate, as in the paper's Fig. 14.

Force law (the foam is viscoelastic)
------------------------------------
=================  ==========================================================
penetration d      ``surface_y(z) - y`` in mm (0 outside the strip); the foam
                   part is ``d_f = min(d, thickness_mm)``
elastic depth u    ``d_f * (d_f / d_ref) ** (n - 1)`` mm, ``n =
                   stiffening_exponent``, ``d_ref = stiffening_reference_mm``
                   (``u = d_f`` exactly at the default ``n = 1``)
normal force N     ``k(z) * max(0, u + relaxation_ratio * q) * (1 + h * s)`` N;
                   beyond the foam the rigid backing adds
                   ``backing_n_per_mm * (d - thickness_mm)``
relaxing part q    a standard linear solid on u: ``dq/dt = du/dt - q /
                   relaxation_time_s`` (mm); a step indentation first meets
                   ``(1 + ratio)`` times the elastic force and relaxes to it
                   with time constant ``relaxation_time_s``
hysteresis s       dimensionless, in [-1, 1]; ``h = hysteresis_loss``; see below
direction          outward normal ``(0, 1, -surface_y'(z))``, normalised
friction           ``-friction_coefficient * N * t``: t is the unit direction
                   of the tool's last slide along the surface (see below)
=================  ==========================================================

The three terms below are off by default (today's linear, elastic, frictionless
sponge) and each is a key of ``[emulator.sponge]``.

*Nonlinear foam* (``stiffening_exponent`` n, default 1; ``stiffening_reference_mm``
d_ref, default 10 mm, where the law meets the linear one: k stays the secant
stiffness at d_ref). A power law of the depth, the simplest law that reproduces
how flexible open-cell polyurethane stiffens under a flat indenter: the
industry's indentation force-deflection test (ASTM D3574 test B1) reports the
"support factor" IFD(65 %) / IFD(25 %), typically 1.5-3.5 for such foams; a
power law has support factor ``2.6 ** n``, so n = 1 (2.6) is the middle of that
range and n = 1.3 a firm, densifying foam. Beyond ~60 % strain the foam
densifies (Gibson & Ashby, *Cellular Solids*, 2nd ed., 1997, ch. 5), which n > 1
approximates over the depths the task uses. The relaxation acts on the elastic
depth u rather than on d (Fung's quasi-linear viscoelasticity: the relaxation
function multiplies the elastic response), so n = 1 is today's law exactly.

*Hysteresis* (``hysteresis_loss`` h in [0, 0.9], default 0;
``hysteresis_depth_mm`` d_h, default 0.5 mm; ``hysteresis_travel_mm`` L, default
10 mm). A rate-independent Dahl-type term, apart from the rate-dependent
relaxation: the state s follows the foam depth as ``ds = (sign(dd_f) - s) |dd_f|
/ d_h``, so pressing in drives s towards +1 and easing off towards -1 within
about d_h of a reversal. After a press of a few d_h the foam pushes ``(1 + h)``
times its elastic force, and ``(1 - h)`` times it on the way back out at the
same depth: the loading and unloading curves of a foam's compression loop,
whose area (the energy lost per cycle) is about ``2 h`` times the energy
stored. A roller that travels along the surface presses fresh foam, which is
loading: travel t adds ``ds = (1 - s) dt / L`` (L about the contact patch's
length, assumption), so a step down Z that eases off a little stays near the
loading branch, as under a real rolling indenter. Flexible PU foams lose 20-50 % per cycle,
h = 0.1-0.25 (assumption, in line with the hysteresis unloading factor of
LS-DYNA's rate-independent low-density foam, MAT_057). s is 0 out of contact.

*Friction along the motion* (``friction_coefficient`` mu >= 0, default 0). The
roller drags the foam's skin along: the tangential force on the tool is
``mu * N`` opposite to the direction t of its last slide along the surface
(the last displacement while in contact, less its component along the
surface normal; a move within ~6 degrees of the normal, pressing in or easing
off, slides nothing and keeps the last direction). It stays while the tool
rests (the sheared skin holds it), so a force read after the arm settles shows
it; it vanishes when the tool leaves the foam. It appears in the sensor's
wrench (Fz and the moments, for the §5 path down Z) and hardly in the normal
force.

Time enters only through :meth:`Sponge.evolve`, called by the cell physics
on its motion grid (``q`` is integrated exactly for a depth that changes
linearly within a tick). Without calls to it the sponge is quasi-static.

Defaults and why
----------------
``stiffness_n_per_mm = 2.0``: the paper's desired 2 kgf (19.61 N) is then
reached at about 10 mm of compression (a quarter of a 40 mm sponge), so a
position step of a few mm changes the force by several newtons, fine enough
for the learner and coarse enough to matter. Stiffness varies +-15 % over a
120 mm wavelength; the surface tilts 3 mm per 100 mm and waves +-1 mm over
80 mm, so over the paper's 20 steps of -5 mm (100 mm) the force at fixed Y
drifts by several newtons. Softening 30 % and a 2 mm set (time constants of
150 and 100 passes) make the initial force of a trial that starts 4 mm deep
fall from 8.6 N to 3.6 N over the paper's ~240 repetitions.

``relaxation_ratio = 0.25`` and ``relaxation_time_s = 0.4`` (assumption: flexible
polyurethane foam loses a fifth to a third of a step's force within a second
or two): a force read 0.1-0.3 s after a 1 mm step is still 10-20 % of the
step's force above its relaxed value. ``relaxation_ratio = 0`` turns time off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SpongeParams:
    """Every parameter of the sponge; lengths in mm, stiffness in N/mm."""

    surface_y_mm: float = 0.0
    """Surface Y at ``z_top_mm`` before any pass."""
    z_top_mm: float = 20.0
    """Upper end of the strip (the trajectory starts below it)."""
    z_bottom_mm: float = -120.0
    """Lower end of the strip."""
    thickness_mm: float = 40.0
    """Foam thickness; beyond it the tool meets the rigid backing."""
    surface_slope: float = 0.03
    """dY/d(-Z) of the surface: mm of surface rise per mm travelled down."""
    waviness_mm: float = 1.0
    """Amplitude of the surface waviness."""
    waviness_wavelength_mm: float = 80.0
    """Wavelength of the surface waviness along Z."""
    stiffness_n_per_mm: float = 2.0
    """Mean stiffness k0 of the fresh foam."""
    stiffness_variation: float = 0.15
    """Relative amplitude of the stiffness variation along Z."""
    stiffness_wavelength_mm: float = 120.0
    """Wavelength of the stiffness variation along Z."""
    backing_n_per_mm: float = 200.0
    """Stiffness of the rigid backing met beyond ``thickness_mm``."""
    softening: float = 0.30
    """Fraction of stiffness lost after many passes."""
    softening_passes: float = 150.0
    """Passes for the softening to reach 63 % of its final value."""
    set_mm: float = 2.0
    """Final permanent set (the surface sinks by this much)."""
    set_passes: float = 100.0
    """Passes for the set to reach 63 % of its final value."""
    relaxation_ratio: float = 0.25
    """Extra stiffness of a fresh indentation, as a fraction of k (0: no relaxation)."""
    relaxation_time_s: float = 0.4
    """Time constant of the stress relaxation, s."""
    stiffening_exponent: float = 1.0
    """Power n of the force-depth law (1: linear; > 1: the foam stiffens as it compresses)."""
    stiffening_reference_mm: float = 10.0
    """Depth (mm) at which the power law equals the linear law ``k * d``."""
    hysteresis_loss: float = 0.0
    """Loading force is ``(1 + h)``, unloading ``(1 - h)`` times the elastic force (0: off)."""
    hysteresis_depth_mm: float = 0.5
    """Depth change (mm) over which the hysteresis switches branch after a reversal."""
    hysteresis_travel_mm: float = 10.0
    """Travel along the surface (mm) after which the roller presses fresh foam (loading)."""
    friction_coefficient: float = 0.0
    """mu: tangential force ``mu * N`` against the tool's last slide (0: no friction)."""

    def __post_init__(self) -> None:
        positive = ("thickness_mm", "waviness_wavelength_mm", "stiffness_n_per_mm",
                    "stiffness_wavelength_mm", "backing_n_per_mm", "softening_passes",
                    "set_passes", "relaxation_time_s", "stiffening_reference_mm",
                    "hysteresis_depth_mm", "hysteresis_travel_mm")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"sponge {name} must be > 0, got {getattr(self, name)}")
        if self.z_bottom_mm >= self.z_top_mm:
            raise ValueError("sponge z_bottom_mm must be below z_top_mm")
        if not 0 <= self.softening < 1 or not 0 <= self.stiffness_variation < 1:
            raise ValueError("sponge softening and stiffness_variation must be in [0, 1)")
        if not 0 <= self.relaxation_ratio <= 10:
            raise ValueError("sponge relaxation_ratio must be in [0, 10]")
        if not 0.5 <= self.stiffening_exponent <= 3:
            raise ValueError("sponge stiffening_exponent must be in [0.5, 3] (1: a linear foam, "
                             f"1.1-1.5: one that stiffens), got {self.stiffening_exponent}")
        if not 0 <= self.hysteresis_loss <= 0.9:
            raise ValueError(f"sponge hysteresis_loss must be in [0, 0.9] (0: off, 0.1-0.25: "
                             f"a flexible PU foam), got {self.hysteresis_loss}")
        if not 0 <= self.friction_coefficient <= 2:
            raise ValueError(f"sponge friction_coefficient must be in [0, 2] (0: off, "
                             f"0.1-0.5: a roller on foam), got {self.friction_coefficient}")


def surface_y_mm(params: SpongeParams, passes: float, z_mm: float) -> float:
    """Return the surface Y (mm) at height ``z_mm`` after ``passes`` passes."""
    travelled = params.z_top_mm - z_mm
    wave = params.waviness_mm * math.sin(2 * math.pi * travelled / params.waviness_wavelength_mm)
    sunk = params.set_mm * (1 - math.exp(-passes / params.set_passes))
    return float(params.surface_y_mm + params.surface_slope * travelled + wave - sunk)


def _surface_slope_dy_dz(params: SpongeParams, z_mm: float) -> float:
    travelled = params.z_top_mm - z_mm
    k = 2 * math.pi / params.waviness_wavelength_mm
    return float(-params.surface_slope - params.waviness_mm * k * math.cos(k * travelled))


def stiffness_n_per_mm(params: SpongeParams, passes: float, z_mm: float) -> float:
    """Return the foam stiffness (N/mm) at height ``z_mm`` after ``passes`` passes."""
    travelled = params.z_top_mm - z_mm
    variation = params.stiffness_variation * math.cos(
        2 * math.pi * travelled / params.stiffness_wavelength_mm
    )
    softened = 1 - params.softening * (1 - math.exp(-passes / params.softening_passes))
    return float(params.stiffness_n_per_mm * (1 + variation) * softened)


def penetration_mm(params: SpongeParams, passes: float, position_mm: np.ndarray) -> float:
    """Return how deep (mm, >= 0) the tool point is in the sponge; 0 off the strip."""
    y, z = float(position_mm[1]), float(position_mm[2])  # floats: numpy scalars are slower
    if not params.z_bottom_mm <= z <= params.z_top_mm:
        return 0.0
    return max(0.0, surface_y_mm(params, passes, z) - y)


def elastic_depth_mm(params: SpongeParams, foam_mm: float) -> float:
    """Return the elastic depth u (mm) of a foam depth ``foam_mm``: ``k * u`` is its force.

    ``u = d * (d / d_ref) ** (n - 1)``; exactly ``foam_mm`` for a linear foam (n = 1).
    """
    n = params.stiffening_exponent
    if n == 1.0 or foam_mm <= 0.0:
        return foam_mm
    return float(foam_mm * (foam_mm / params.stiffening_reference_mm) ** (n - 1.0))


def surface_normal(params: SpongeParams, z_mm: float) -> np.ndarray:
    """Return the sponge's outward unit normal (3,) at height ``z_mm``."""
    direction = np.array([0.0, 1.0, -_surface_slope_dy_dz(params, z_mm)])
    unit: np.ndarray = direction / np.linalg.norm(direction)
    return unit


def contact_force_n(
    params: SpongeParams,
    passes: float,
    position_mm: np.ndarray,
    relaxing_mm: float = 0.0,
    hysteresis_state: float = 0.0,
    slide_direction: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Return the sponge's reaction force (3,) in N, world frame, on a tool point (mm).

    ``relaxing_mm`` is the standard linear solid's relaxing part q (0: relaxed),
    ``hysteresis_state`` the Dahl state s in [-1, 1] (0: neutral), and
    ``slide_direction`` the unit direction of the tool's last slide along the
    surface (zeros: no slide yet, no friction).
    """
    depth = penetration_mm(params, passes, position_mm)
    if depth <= 0.0:
        return np.zeros(3)
    z = float(position_mm[2])
    elastic_mm = elastic_depth_mm(params, min(depth, params.thickness_mm))
    foam_mm = max(0.0, elastic_mm + params.relaxation_ratio * relaxing_mm)
    normal_n = stiffness_n_per_mm(params, passes, z) * foam_mm
    if params.hysteresis_loss != 0.0:
        normal_n *= 1.0 + params.hysteresis_loss * hysteresis_state
    normal_n += params.backing_n_per_mm * max(0.0, depth - params.thickness_mm)
    direction = np.array([0.0, 1.0, -_surface_slope_dy_dz(params, z)])
    force = normal_n * direction / np.linalg.norm(direction)
    if params.friction_coefficient != 0.0 and any(slide_direction):
        force = force - params.friction_coefficient * normal_n * np.asarray(slide_direction)
    return force


SLIDE_MIN_FRACTION = 0.1
"""A move slides the roller when its part along the surface is at least this fraction of it
(more than ~6 degrees off the normal); a press along Y on the tilted surface does not."""


def hysteresis_step(
    params: SpongeParams, state: float, change_mm: float, travel_mm: float = 0.0
) -> float:
    """Return the Dahl state s after a straight move of the tool.

    The foam depth changed by ``change_mm`` (mm) while the roller travelled
    ``travel_mm`` (mm) along the surface onto fresh foam. Along the move
    ``ds = (sign - s) |dd| / d_h + (1 - s) dt / L``, solved exactly for a
    straight move: s tends to ``(a sign + b) / (a + b)`` at rate ``a + b``,
    ``a = |change| / d_h``, ``b = travel / L``.
    """
    a = abs(change_mm) / params.hysteresis_depth_mm
    b = travel_mm / params.hysteresis_travel_mm
    if a + b == 0.0:
        return state
    sign = 1.0 if change_mm > 0.0 else -1.0
    target = (a * sign + b) / (a + b)
    return target + (state - target) * math.exp(-(a + b))


def slide_direction(
    params: SpongeParams, move_mm: np.ndarray, z_mm: float
) -> tuple[float, float, float] | None:
    """Return the unit direction of a move (mm) along the surface at ``z_mm``.

    The move less its component along the surface normal; None for a move
    within ``SLIDE_MIN_FRACTION`` of the normal (pressing in or easing off),
    which slides nothing.
    """
    normal = surface_normal(params, z_mm)
    along = move_mm - float(move_mm @ normal) * normal
    length = float(np.linalg.norm(along))
    if length < SLIDE_MIN_FRACTION * float(np.linalg.norm(move_mm)) or length < 1e-9:
        return None
    unit = along / length
    return (float(unit[0]), float(unit[1]), float(unit[2]))


class Sponge:
    """A sponge that counts its passes; a ``ContactEnvironment`` for :class:`CellPhysics`.

    A pass is counted each time the tool, having been in contact, leaves the
    sponge (pulls out of it or runs off either end of the strip). The robot
    emulator reports poses through :meth:`observe_pose`; :meth:`finish_pass`
    counts one by hand. The same reports drive the hysteresis state and the
    direction of the last slide (friction). ``state_dict``/``load_state_dict``
    save and restore it. Not thread-safe on its own: :class:`CellPhysics`
    serialises calls.
    """

    def __init__(self, params: SpongeParams | None = None, passes: int = 0) -> None:
        self.params = params or SpongeParams()
        self.passes = passes
        self._touched = False
        self.relaxing_mm = 0.0
        """The relaxing part q of the standard linear solid, mm."""
        self._foam_mm = 0.0
        self.hysteresis_state = 0.0
        """The Dahl state s in [-1, 1] (+1: pressing in, -1: easing off)."""
        self._hysteresis_foam_mm = 0.0
        """The foam depth the hysteresis state was last brought to, mm."""
        self.slide_direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
        """Unit direction of the tool's last slide along the surface (zeros: none)."""
        self._last_position: tuple[float, float, float] | None = None
        """Where the tool was at the last report (friction only), mm."""
        self._memo_key: tuple[float, ...] | None = None
        self._memo_force = np.zeros(3)
        self._depth_key: tuple[float, ...] | None = None
        self._depth_mm = 0.0

    def _penetration_mm(self, position_mm: np.ndarray) -> float:
        """:func:`penetration_mm` at the present pass count, remembered for the last position."""
        key = (self.passes, float(position_mm[1]), float(position_mm[2]))
        if key != self._depth_key:  # asked once per pose and once per motion tick
            self._depth_key = key
            self._depth_mm = penetration_mm(self.params, self.passes, position_mm)
        return self._depth_mm

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        """Return the reaction force (3,) in N, world frame, at the present pass count."""
        coords = position_mm.tolist() if isinstance(position_mm, np.ndarray) else position_mm
        key = (self.passes, self.relaxing_mm, self.hysteresis_state, *self.slide_direction,
               *(float(c) for c in coords))
        if key != self._memo_key:  # the sensor asks thousands of times per pose
            self._memo_key = key
            self._memo_force = contact_force_n(
                self.params, self.passes, position_mm, self.relaxing_mm,
                self.hysteresis_state, self.slide_direction,
            )
        return self._memo_force.copy()

    def evolve(self, position_mm: np.ndarray, dt_s: float) -> None:
        """Advance the relaxation over ``dt_s`` during which the tool moved to ``position_mm``.

        The elastic depth is taken to change linearly over the interval (exact
        for the standard linear solid under a ramp).
        """
        p = self.params
        foam = elastic_depth_mm(p, min(self._penetration_mm(position_mm), p.thickness_mm))
        change, self._foam_mm = foam - self._foam_mm, foam
        if p.relaxation_ratio == 0.0 or dt_s <= 0.0:
            self.relaxing_mm = 0.0
            return
        keep = math.exp(-dt_s / p.relaxation_time_s)
        self.relaxing_mm = self.relaxing_mm * keep + change * (p.relaxation_time_s / dt_s) * (
            1.0 - keep
        )
        if foam == 0.0 and self.relaxing_mm > 0.0:
            self.relaxing_mm = 0.0  # out of contact the foam recovers freely

    def observe_pose(self, position_mm: np.ndarray) -> None:
        """Note where the tool is; completes a pass when it leaves the sponge after contact."""
        depth = self._penetration_mm(position_mm)
        p = self.params
        if p.hysteresis_loss != 0.0 or p.friction_coefficient != 0.0:
            self._follow_move(position_mm, depth)
        if depth > 0.0:
            self._touched = True
        elif self._touched:
            self.finish_pass()

    def _follow_move(self, position_mm: np.ndarray, depth_mm: float) -> None:
        """Bring the hysteresis state and the last slide to a reported pose."""
        p = self.params
        here = (float(position_mm[0]), float(position_mm[1]), float(position_mm[2]))
        last, self._last_position = self._last_position, here
        if depth_mm <= 0.0:  # off the foam: it forgets its branch, nothing holds its skin
            self.hysteresis_state = 0.0
            self._hysteresis_foam_mm = 0.0
            self.slide_direction = (0.0, 0.0, 0.0)
            return
        move = np.subtract(here, last) if last is not None and last != here else None
        along_mm = 0.0  # travel along the surface; a press within ~6 degrees of the normal: none
        if move is not None:
            normal = surface_normal(p, here[2])
            along_mm = float(np.linalg.norm(move - float(move @ normal) * normal))
            if along_mm < SLIDE_MIN_FRACTION * float(np.linalg.norm(move)):
                along_mm = 0.0
        if p.hysteresis_loss != 0.0:
            foam = min(depth_mm, p.thickness_mm)
            self.hysteresis_state = hysteresis_step(
                p, self.hysteresis_state, foam - self._hysteresis_foam_mm, along_mm
            )
            self._hysteresis_foam_mm = foam
        if p.friction_coefficient != 0.0 and move is not None:
            direction = slide_direction(p, move, here[2])
            if direction is not None:
                self.slide_direction = direction

    def finish_pass(self) -> None:
        """Count one pass now."""
        self.passes += 1
        self._touched = False

    def state_dict(self) -> dict[str, int | bool | float]:
        """Return the state to checkpoint (plain numbers)."""
        state: dict[str, int | bool | float] = {
            "passes": self.passes,
            "touched": self._touched,
            "relaxing_mm": self.relaxing_mm,
            "foam_mm": self._foam_mm,
            "hysteresis_state": self.hysteresis_state,
            "hysteresis_foam_mm": self._hysteresis_foam_mm,
            "has_last_position": self._last_position is not None,
        }
        for axis, value in zip("xyz", self.slide_direction, strict=True):
            state[f"slide_{axis}"] = value
        for axis, value in zip("xyz", self._last_position or (0.0, 0.0, 0.0), strict=True):
            state[f"last_{axis}_mm"] = value
        return state

    def load_state_dict(self, state: dict[str, int | bool | float]) -> None:
        """Restore a state from :meth:`state_dict` (keys it lacks take their fresh values)."""
        self.passes = int(state["passes"])
        self._touched = bool(state["touched"])
        self.relaxing_mm = float(state.get("relaxing_mm", 0.0))
        self._foam_mm = float(state.get("foam_mm", 0.0))
        self.hysteresis_state = float(state.get("hysteresis_state", 0.0))
        self._hysteresis_foam_mm = float(state.get("hysteresis_foam_mm", 0.0))
        x, y, z = (float(state.get(f"slide_{axis}", 0.0)) for axis in "xyz")
        self.slide_direction = (x, y, z)
        self._last_position = None
        if state.get("has_last_position", False):
            x, y, z = (float(state[f"last_{axis}_mm"]) for axis in "xyz")
            self._last_position = (x, y, z)
