"""The sponge's law (the paper's §5 foam strip): pure functions over arrays of its frozen params.

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

Time enters only through :meth:`~forcelearn.emulators.physics.sponge.Sponge.evolve`,
called by the cell physics on its motion grid (``q`` is integrated exactly for
a depth that changes linearly within a tick, :func:`relaxation_step`). Without
calls to it the sponge is quasi-static.

One law, two callers
--------------------
Every function here takes a Python float or a numpy array for each point
argument (passes, Y, Z, depth, state), elementwise: floats in, a float out
(the emulated sponge, :class:`~forcelearn.emulators.physics.sponge.Sponge`,
one pose at a time, with :mod:`math` for speed); arrays in, an array out (the
twin's forward model, ``forcelearn.tools.twin.forward``, a run's bursts at
once). The expressions are the same, so the two agree to rounding (a test
checks 1e-12 on every member of the foam family). :func:`depth_for_force_mm`
is the law's inverse. A new term of the foam goes here, once.

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

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any, TypeVar

import numpy as np

F = TypeVar("F", float, np.ndarray)
"""A point argument: one float (the emulated sponge's pose) or an array of points (the twin's)."""

SLIDE_MIN_FRACTION = 0.1
"""A move slides the roller when its part along the surface is at least this fraction of it
(more than ~6 degrees off the normal); a press along Y on the tilted surface does not."""
SLIDE_MIN_MM = 1e-9
"""...and at least this long (mm): shorter is no direction."""


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

    @classmethod
    def unchecked(cls, values: Mapping[str, float]) -> SpongeParams:
        """The params of ``values`` (a field missing: its default) without the range checks.

        For a fit's trial points, which may stray beyond a config's ranges (a stiffening
        exponent of 0.4); a config is always loaded through the checked constructor.
        """
        params = object.__new__(cls)
        for spec in dataclasses.fields(cls):
            object.__setattr__(params, spec.name, values.get(spec.name, spec.default))
        return params


# Elementwise helpers: math on floats (the emulator's hot path), numpy on arrays.


def _elementwise(
    array_fn: Callable[[np.ndarray], np.ndarray], float_fn: Callable[[float], float]
) -> Callable[[F], F]:
    """One function of ``x``: ``array_fn`` on arrays, ``float_fn`` on floats."""

    def apply(x: F) -> F:
        if isinstance(x, np.ndarray):
            result: np.ndarray = array_fn(x)
            return result
        return float_fn(x)

    return apply


_sin = _elementwise(np.sin, math.sin)
_cos = _elementwise(np.cos, math.cos)
_exp = _elementwise(np.exp, math.exp)
_positive = _elementwise(partial(np.maximum, 0.0), lambda x: x if x > 0.0 else 0.0)
"""``max(0, x)`` (on floats written out: what ``max(0.0, x)`` returns, NaN included, faster)."""


def _at_most(x: F, limit: float) -> F:
    """``min(x, limit)``."""
    if isinstance(x, np.ndarray):
        result: np.ndarray = np.minimum(x, limit)
        return result
    return min(x, limit)


def _where(condition: F, value: F, otherwise: float) -> F:
    """``value`` where ``condition`` is nonzero (True), else ``otherwise``."""
    if isinstance(condition, np.ndarray) or isinstance(value, np.ndarray):
        result: np.ndarray = np.where(condition, value, otherwise)
        return result
    return value if condition else otherwise


def _norm(vector: np.ndarray) -> np.ndarray:
    """Euclidean length over the last axis, kept as an axis of 1 for arrays of vectors."""
    if vector.ndim == 1:
        return np.asarray(np.linalg.norm(vector))
    return np.asarray(np.linalg.norm(vector, axis=-1, keepdims=True))


def set_depth_mm(params: SpongeParams, passes: F) -> F:
    """Return how far (mm) the surface has sunk after ``passes`` passes (its set)."""
    return params.set_mm * (1 - _exp(-passes / params.set_passes))


def surface_y_mm(params: SpongeParams, passes: F, z_mm: F) -> F:
    """Return the surface Y (mm) at height ``z_mm`` after ``passes`` passes."""
    return set_surface_y_mm(params, set_depth_mm(params, passes), z_mm)


def set_surface_y_mm(params: SpongeParams, set_mm: F, z_mm: F) -> F:
    """Return the surface Y (mm) at height ``z_mm`` once it has sunk ``set_mm`` (its set)."""
    return _surface_y_mm(params, set_mm, z_mm, _sin)


def _surface_y_mm(params: SpongeParams, set_mm: F, z_mm: F, sin: Callable[[F], F]) -> F:
    """:func:`set_surface_y_mm` with ``sin`` (``math.sin`` for one point: the hot path)."""
    travelled = params.z_top_mm - z_mm
    wave = params.waviness_mm * sin(2 * math.pi * travelled / params.waviness_wavelength_mm)
    surface: F = params.surface_y_mm + params.surface_slope * travelled + wave - set_mm
    return surface


def surface_dy_dz(params: SpongeParams, z_mm: F) -> F:
    """Return the surface's slope dY/dZ at height ``z_mm`` (passes do not change it)."""
    travelled = params.z_top_mm - z_mm
    k = 2 * math.pi / params.waviness_wavelength_mm
    return -params.surface_slope - params.waviness_mm * k * _cos(k * travelled)


def stiffness_n_per_mm(params: SpongeParams, passes: F, z_mm: F) -> F:
    """Return the foam stiffness (N/mm) at height ``z_mm`` after ``passes`` passes."""
    travelled = params.z_top_mm - z_mm
    variation = params.stiffness_variation * _cos(
        2 * math.pi * travelled / params.stiffness_wavelength_mm
    )
    softened = 1 - params.softening * (1 - _exp(-passes / params.softening_passes))
    return params.stiffness_n_per_mm * (1 + variation) * softened


def penetration_mm(params: SpongeParams, passes: F, y_mm: F, z_mm: F) -> F:
    """Return how deep (mm, >= 0) a tool point at (``y_mm``, ``z_mm``) is; 0 off the strip."""
    if isinstance(z_mm, np.ndarray) or isinstance(y_mm, np.ndarray):
        inside = (z_mm >= params.z_bottom_mm) & (z_mm <= params.z_top_mm)
        depth: np.ndarray = np.where(
            inside, np.maximum(0.0, surface_y_mm(params, passes, z_mm) - y_mm), 0.0)
        return depth
    return point_penetration_mm(params, set_depth_mm(params, passes), y_mm, z_mm)


def point_penetration_mm(params: SpongeParams, set_mm: float, y_mm: float, z_mm: float) -> float:
    """:func:`penetration_mm` of one point (floats) on the surface sunk ``set_mm`` (hot path)."""
    if not params.z_bottom_mm <= z_mm <= params.z_top_mm:
        return 0.0
    # _surface_y_mm(params, set_mm, z_mm, math.sin) written out (once per motion tick)
    travelled = params.z_top_mm - z_mm
    wave = params.waviness_mm * math.sin(2 * math.pi * travelled / params.waviness_wavelength_mm)
    surface = params.surface_y_mm + params.surface_slope * travelled + wave - set_mm
    return max(0.0, surface - y_mm)


def elastic_depth_mm(params: SpongeParams, foam_mm: F) -> F:
    """Return the elastic depth u (mm) of a foam depth ``foam_mm``: ``k * u`` is its force.

    ``u = d * (d / d_ref) ** (n - 1)``; exactly ``foam_mm`` for a linear foam (n = 1) and
    where ``foam_mm <= 0``.
    """
    n = params.stiffening_exponent
    if n == 1.0:
        return foam_mm
    reference = params.stiffening_reference_mm
    if isinstance(foam_mm, np.ndarray):
        pressed = foam_mm > 0.0
        safe = np.where(pressed, foam_mm, 1.0)
        result: np.ndarray = np.where(pressed, safe * (safe / reference) ** (n - 1.0), foam_mm)
        return result
    if foam_mm <= 0.0:
        return foam_mm
    return float(foam_mm * (foam_mm / reference) ** (n - 1.0))


def normal_force_n(params: SpongeParams, passes: F, depth_mm: F, z_mm: F,
                   relaxing_mm: F | float = 0.0, hysteresis_state: F | float = 0.0) -> F:
    """Return the normal force N (N) of the foam and its backing at penetration ``depth_mm``.

    ``k(z) * max(0, u + relaxation_ratio * q) * (1 + h * s)`` plus the backing beyond the
    foam (module docstring); ``relaxing_mm`` is q, ``hysteresis_state`` s; 0 out of contact.
    """
    if not isinstance(depth_mm, np.ndarray) and depth_mm <= 0.0:
        return 0.0
    elastic_mm = elastic_depth_mm(params, _at_most(depth_mm, params.thickness_mm))
    foam_mm = _positive(elastic_mm + params.relaxation_ratio * relaxing_mm)
    normal = stiffness_n_per_mm(params, passes, z_mm) * foam_mm
    if params.hysteresis_loss != 0.0:
        normal = normal * (1.0 + params.hysteresis_loss * hysteresis_state)
    normal = normal + params.backing_n_per_mm * _positive(depth_mm - params.thickness_mm)
    return _where(depth_mm > 0.0, normal, 0.0)


def surface_direction(params: SpongeParams, z_mm: F) -> np.ndarray:
    """Return the outward normal, not normalised: ``(0, 1, -dY/dZ)``, (3,) or (..., 3)."""
    slope = surface_dy_dz(params, z_mm)
    if isinstance(slope, np.ndarray):
        return np.stack([np.zeros_like(slope), np.ones_like(slope), -slope], axis=-1)
    return np.array([0.0, 1.0, -slope])


def surface_normal(params: SpongeParams, z_mm: F) -> np.ndarray:
    """Return the sponge's outward unit normal at height ``z_mm``, (3,) or (..., 3)."""
    direction = surface_direction(params, z_mm)
    unit: np.ndarray = direction / _norm(direction)
    return unit


def contact_force_n(
    params: SpongeParams,
    passes: F,
    position_mm: np.ndarray,
    relaxing_mm: F | float = 0.0,
    hysteresis_state: F | float = 0.0,
    slide_direction: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Return the sponge's reaction force in N, world frame, on tool points (mm).

    ``position_mm`` is one point (3,) (floats throughout: the emulator's pose) or
    points (..., 3), each with its ``passes``, ``relaxing_mm`` (the standard linear
    solid's relaxing part q; 0: relaxed), ``hysteresis_state`` (the Dahl state s in
    [-1, 1]; 0: neutral) and ``slide_direction`` (the unit direction (3,) or (..., 3)
    of the tool's last slide along the surface; zeros: no slide, no friction). The
    force has the points' shape.
    """
    one = position_mm.ndim == 1
    y: Any = float(position_mm[1]) if one else position_mm[..., 1]  # one: floats, faster
    z: Any = float(position_mm[2]) if one else position_mm[..., 2]
    depth = penetration_mm(params, passes, y, z)
    if one:
        return point_contact_force_n(params, passes, depth, z, relaxing_mm, hysteresis_state,
                                     slide_direction, *direction_terms(params, z))
    normal: Any = normal_force_n(params, passes, depth, z, relaxing_mm, hysteresis_state)
    normal_n = normal if one else normal[..., None]
    direction = surface_direction(params, z)
    force: np.ndarray = normal_n * direction / _norm(direction)
    if params.friction_coefficient != 0.0 and np.any(slide_direction):
        force = force - params.friction_coefficient * normal_n * np.asarray(slide_direction)
    return force


def direction_terms(params: SpongeParams, z_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The outward normal at ``z_mm`` not normalised, and its length: what the force divides.

    ``(surface_direction(params, z_mm), _norm(...))`` of one point; the same for every
    depth and pass count at that height (a caller may keep them per height).
    """
    direction = surface_direction(params, z_mm)
    return direction, _norm(direction)


def point_contact_force_n(
    params: SpongeParams,
    passes: Any,
    depth_mm: float,
    z_mm: float,
    relaxing_mm: Any,
    hysteresis_state: Any,
    slide_direction: tuple[float, float, float] | np.ndarray,
    direction: np.ndarray,
    norm: np.ndarray,
) -> np.ndarray:
    """:func:`contact_force_n` of one point ``depth_mm`` deep (``penetration_mm``) at ``z_mm``.

    ``direction`` and ``norm`` are :func:`direction_terms` at ``z_mm``; ``passes``,
    ``relaxing_mm`` and ``hysteresis_state`` are the point's (numbers); (3,) N, world frame.
    """
    if depth_mm <= 0.0:
        return np.zeros(3)
    normal = normal_force_n(params, passes, depth_mm, z_mm, relaxing_mm, hysteresis_state)
    force: np.ndarray = normal * direction / norm
    if params.friction_coefficient != 0.0 and np.any(slide_direction):
        force = force - params.friction_coefficient * normal * np.asarray(slide_direction)
    return force


def along_surface_mm(params: SpongeParams, move_mm: np.ndarray, z_mm: F) -> np.ndarray:
    """Return a move's (mm) part along the surface at ``z_mm``: less its part along the normal.

    ``move_mm`` is one move (3,) or moves (..., 3), each at its ``z_mm``.
    """
    normal = surface_normal(params, z_mm)
    if move_mm.ndim == 1:
        return np.asarray(move_mm - float(move_mm @ normal) * normal)
    across = np.sum(move_mm * normal, axis=-1, keepdims=True)
    return np.asarray(move_mm - across * normal)


def slides(along_mm: F, move_mm: F) -> F:
    """True where a move of length ``move_mm`` (mm) slides the roller along the surface.

    Its part along the surface, ``along_mm``, is at least ``SLIDE_MIN_FRACTION`` of it (more
    than ~6 degrees off the normal) and at least ``SLIDE_MIN_MM``: pressing in or easing off
    slides nothing.
    """
    return (along_mm >= SLIDE_MIN_FRACTION * move_mm) & (along_mm >= SLIDE_MIN_MM)


def slide_direction(
    params: SpongeParams, move_mm: np.ndarray, z_mm: float
) -> tuple[float, float, float] | None:
    """Return the unit direction of a move (mm) along the surface at ``z_mm``.

    The move less its component along the surface normal; None for a move
    that does not slide (:func:`slides`).
    """
    along = along_surface_mm(params, move_mm, z_mm)
    length = float(np.linalg.norm(along))
    if not slides(length, float(np.linalg.norm(move_mm))):
        return None
    unit = along / length
    return (float(unit[0]), float(unit[1]), float(unit[2]))


def hysteresis_target(params: SpongeParams, change_mm: F,
                      travel_mm: F | float) -> tuple[F, F]:
    """Return where the Dahl state s tends and at what rate along a straight move.

    The foam depth changed by ``change_mm`` (mm) while the roller travelled
    ``travel_mm`` (mm) along the surface onto fresh foam: ``ds = (sign - s) |dd| /
    d_h + (1 - s) dt / L`` takes s towards ``(a sign + b) / (a + b)`` at rate ``a +
    b``, ``a = |change| / d_h``, ``b = travel / L`` (target 0 at rate 0: no change).
    """
    a = abs(change_mm) / params.hysteresis_depth_mm
    b = travel_mm / params.hysteresis_travel_mm
    rate = a + b
    if isinstance(rate, np.ndarray):
        sign = np.where(change_mm > 0.0, 1.0, -1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            target: np.ndarray = np.where(rate > 0.0, (a * sign + b) / rate, 0.0)
        return target, rate
    sign = 1.0 if change_mm > 0.0 else -1.0
    return ((a * sign + b) / rate if rate > 0.0 else 0.0), rate


def hysteresis_step(params: SpongeParams, state: F, change_mm: F,
                    travel_mm: F | float = 0.0) -> F:
    """Return the Dahl state s after a straight move of the tool (:func:`hysteresis_target`).

    Solved exactly for a straight move: ``target + (s - target) exp(-rate)``.
    """
    target, rate = hysteresis_target(params, change_mm, travel_mm)
    if not isinstance(rate, np.ndarray) and rate == 0.0:
        return state
    result: F = target + (state - target) * _exp(-rate)
    return result


def relaxation_step(params: SpongeParams, relaxing_mm: F, change_mm: F, dt_s: float) -> F:
    """Return the relaxing part q (mm) after a ramp of the elastic depth.

    The depth changed linearly by ``change_mm`` over ``dt_s`` > 0 s: the standard linear
    solid's exact answer.
    """
    keep = math.exp(-dt_s / params.relaxation_time_s)
    return relaxing_mm * keep + change_mm * (params.relaxation_time_s / dt_s) * (1.0 - keep)


def depth_for_force_mm(params: SpongeParams, force_n: F, stiffness_n_per_mm: F) -> F:
    """Return the foam depth (mm) at which foam of ``stiffness_n_per_mm`` pushes ``force_n``.

    The law's inverse for a relaxed foam, ``k * d * (d / d_ref) ** (n - 1) = force`` (N,
    N/mm), without hysteresis or backing.
    """
    n, reference = params.stiffening_exponent, params.stiffening_reference_mm
    depth: F = (force_n / stiffness_n_per_mm * reference ** (n - 1.0)) ** (1.0 / n)
    return depth
