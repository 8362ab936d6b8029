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

Force law (no friction; the foam is viscoelastic)
--------------------------------------------------
=================  ==========================================================
penetration d      ``surface_y(z) - y`` in mm (0 outside the strip); the foam
                   part is ``d_f = min(d, thickness_mm)``
normal force       ``k(z) * max(0, d_f + relaxation_ratio * q)`` N; beyond the
                   foam the rigid backing adds ``backing_n_per_mm * (d - thickness_mm)``
relaxing part q    a standard linear solid: ``dq/dt = dd_f/dt - q / relaxation_time_s``
                   (mm); a step indentation first meets ``(1 + ratio) k`` and
                   relaxes to ``k`` with time constant ``relaxation_time_s``
direction          outward normal ``(0, 1, -surface_y'(z))``, normalised
=================  ==========================================================

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

    def __post_init__(self) -> None:
        positive = ("thickness_mm", "waviness_wavelength_mm", "stiffness_n_per_mm",
                    "stiffness_wavelength_mm", "backing_n_per_mm", "softening_passes",
                    "set_passes", "relaxation_time_s")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"sponge {name} must be > 0, got {getattr(self, name)}")
        if self.z_bottom_mm >= self.z_top_mm:
            raise ValueError("sponge z_bottom_mm must be below z_top_mm")
        if not 0 <= self.softening < 1 or not 0 <= self.stiffness_variation < 1:
            raise ValueError("sponge softening and stiffness_variation must be in [0, 1)")
        if not 0 <= self.relaxation_ratio <= 10:
            raise ValueError("sponge relaxation_ratio must be in [0, 10]")


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


def contact_force_n(
    params: SpongeParams, passes: float, position_mm: np.ndarray, relaxing_mm: float = 0.0
) -> np.ndarray:
    """Return the sponge's reaction force (3,) in N, world frame, on a tool point (mm).

    ``relaxing_mm`` is the standard linear solid's relaxing part q (0: relaxed).
    """
    depth = penetration_mm(params, passes, position_mm)
    if depth <= 0.0:
        return np.zeros(3)
    z = float(position_mm[2])
    foam_mm = max(0.0, min(depth, params.thickness_mm) + params.relaxation_ratio * relaxing_mm)
    normal_n = stiffness_n_per_mm(params, passes, z) * foam_mm
    normal_n += params.backing_n_per_mm * max(0.0, depth - params.thickness_mm)
    direction = np.array([0.0, 1.0, -_surface_slope_dy_dz(params, z)])
    return normal_n * direction / np.linalg.norm(direction)


class Sponge:
    """A sponge that counts its passes; a ``ContactEnvironment`` for :class:`CellPhysics`.

    A pass is counted each time the tool, having been in contact, leaves the
    sponge (pulls out of it or runs off either end of the strip). The robot
    emulator reports poses through :meth:`observe_pose`; :meth:`finish_pass`
    counts one by hand. ``state_dict``/``load_state_dict`` save and restore it.
    Not thread-safe on its own: :class:`CellPhysics` serialises calls.
    """

    def __init__(self, params: SpongeParams | None = None, passes: int = 0) -> None:
        self.params = params or SpongeParams()
        self.passes = passes
        self._touched = False
        self.relaxing_mm = 0.0
        """The relaxing part q of the standard linear solid, mm."""
        self._foam_mm = 0.0
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
        key = (self.passes, self.relaxing_mm, *(float(c) for c in coords))
        if key != self._memo_key:  # the sensor asks thousands of times per pose
            self._memo_key = key
            self._memo_force = contact_force_n(
                self.params, self.passes, position_mm, self.relaxing_mm
            )
        return self._memo_force.copy()

    def evolve(self, position_mm: np.ndarray, dt_s: float) -> None:
        """Advance the relaxation over ``dt_s`` during which the tool moved to ``position_mm``.

        The foam depth is taken to change linearly over the interval (exact
        for the standard linear solid under a ramp).
        """
        p = self.params
        foam = min(self._penetration_mm(position_mm), p.thickness_mm)
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
        in_contact = self._penetration_mm(position_mm) > 0.0
        if in_contact:
            self._touched = True
        elif self._touched:
            self.finish_pass()

    def finish_pass(self) -> None:
        """Count one pass now."""
        self.passes += 1
        self._touched = False

    def state_dict(self) -> dict[str, int | bool | float]:
        """Return the state to checkpoint (plain numbers)."""
        return {
            "passes": self.passes,
            "touched": self._touched,
            "relaxing_mm": self.relaxing_mm,
            "foam_mm": self._foam_mm,
        }

    def load_state_dict(self, state: dict[str, int | bool | float]) -> None:
        """Restore a state from :meth:`state_dict`."""
        self.passes = int(state["passes"])
        self._touched = bool(state["touched"])
        self.relaxing_mm = float(state.get("relaxing_mm", 0.0))
        self._foam_mm = float(state.get("foam_mm", 0.0))
