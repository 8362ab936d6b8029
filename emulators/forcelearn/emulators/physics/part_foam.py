"""A foam-covered part: the tool pressed against a plane, cylinder, sphere or height map.

Description
-----------
A :class:`PartFoam` is the contact environment of a cell whose config has an
``[emulator.part]`` table (:mod:`.part` gives the geometry). The part is covered
along its outward normal by the foam of ``[emulator.sponge]``: its thickness
``thickness_mm``, stiffness, wear, relaxation and stiffening follow the one foam
law (:mod:`.sponge_law`), called here with the part's geometry in place of the
§5 strip's:

=================  ==========================================================
tip centre c       the tool pose's position (its contact point, the TCP the
                   robot reports) moved ``tip_radius_mm`` back along the tool's
                   press axis (tool z) turned by the pose's orientation
foam depth d       :func:`.part.contact` with ``offset_mm = thickness_mm``, less
                   the permanent set after the passes so far (mm)
normal force N     :func:`.sponge_law.normal_force_n` at depth d and stiffness
                   coordinate ``z`` = the tip's world z (the law's stiffness
                   varies along its z: here over the part's height)
force              ``N n`` N, world frame, along the part's outward normal n
relaxation         the standard linear solid's q, brought up to date on the
                   motion grid (:meth:`evolve`), exactly as the §5 sponge's
=================  ==========================================================

Hysteresis and friction of ``[emulator.sponge]`` follow the law's own terms
(:func:`.sponge_law.hysteresis_step`, :func:`.sponge_law.slides`), with the part's
normal in place of the strip's: at every reported pose the tool's move less its
component along the part's normal n is its slide along the surface; the Dahl
state s follows the foam depth and that travel, and the friction is ``mu N``
against the last slide's direction t, so the force is ``N (1 + h s) n - mu N t``
(tangential to the part: the sensor's axes across the press axis read it). Off
the foam both are forgotten. With both at 0 (the default) nothing of this runs.

The part is a shell: a tip more than ``WALL_MM`` into the rigid material
under the foam is beyond its wall (outside a pipe pressed on its inside, the
far side of a plate) and touches nothing.

``gap_min_mm`` / ``gap_max_mm``: a box (world frame, mm) where the part is cut
away (a slot, a hole, a missing tile): no force inside it, so a taught path
across it loses contact there.

The orientation comes from :meth:`observe_orientation` (the cell physics calls
it whenever the tool turns), so a tilted tool presses where a real one would. A
pass is counted, as on the sponge, each time the tool leaves the foam after
touching it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from forcelearn.emulators.physics.foam_memory import FoamMemory, State
from forcelearn.emulators.physics.part import Part, contact, tip_centres_mm
from forcelearn.emulators.physics.sponge_law import (
    SpongeParams,
    elastic_depth_mm,
    hysteresis_step,
    normal_force_n,
    relaxation_step,
    slides,
)

Quaternion = tuple[float, float, float, float]

WALL_MM = 30.0
"""Thickness of the rigid part under its foam, mm: a tip further in is beyond the part's wall
(e.g. outside a pipe pressed on its inside) and touches nothing. Assumption: no tool gets
there pressing (the backing's 200 N/mm stops it within a millimetre or two)."""


@dataclass(frozen=True)
class PartSetup:
    """The part, the tool tip that touches it and the gap cut into it (mm)."""

    part: Part
    tip_radius_mm: float = 0.0
    """Radius of the tool's tip (a roller or pad seen across its contact; 0: a point)."""
    gap_min_mm: tuple[float, float, float] | None = None
    gap_max_mm: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.tip_radius_mm) and self.tip_radius_mm >= 0):
            raise ValueError(f"tip_radius_mm must be >= 0, got {self.tip_radius_mm}")
        if (self.gap_min_mm is None) != (self.gap_max_mm is None):
            raise ValueError("give both gap_min_mm and gap_max_mm, or neither")
        if self.gap_min_mm is not None and self.gap_max_mm is not None and not np.all(
                np.less(self.gap_min_mm, self.gap_max_mm)):
            raise ValueError(f"gap_min_mm {self.gap_min_mm} must be below gap_max_mm "
                             f"{self.gap_max_mm} on every axis")

    def in_gap(self, centre_mm: np.ndarray) -> bool:
        """True when ``centre_mm`` (3,) lies in the cut-away box."""
        if self.gap_min_mm is None or self.gap_max_mm is None:
            return False
        return bool(np.all(centre_mm >= self.gap_min_mm) and np.all(centre_mm <= self.gap_max_mm))


class PartFoam(FoamMemory):
    """The foam on a part, with its wear and relaxation; a ``ContactEnvironment``.

    Not thread-safe on its own: :class:`~.cell.CellPhysics` serialises calls.
    """

    def __init__(self, setup: PartSetup, params: SpongeParams | None = None,
                 passes: int = 0) -> None:
        self.setup = setup
        self.params = params or SpongeParams()
        super().__init__(passes)
        self._quaternion: Quaternion = (1.0, 0.0, 0.0, 0.0)
        self._key: tuple[float, ...] | None = None
        self._depth = 0.0
        self._normal = np.zeros(3)
        self._z = 0.0

    def observe_orientation(self, quaternion: Quaternion) -> None:
        """Note the tool's orientation (w, x, y, z), sensor frame to world."""
        self._quaternion = quaternion

    def _contact(self, position_mm: np.ndarray) -> tuple[float, np.ndarray, float]:
        """(foam depth mm, outward normal, stiffness coordinate z mm), remembered per pose."""
        radius = self.setup.tip_radius_mm
        x, y, z = position_mm.tolist() if isinstance(position_mm, np.ndarray) else position_mm
        key = (self.passes, x, y, z, *(self._quaternion if radius else ()))
        if key != self._key:
            self._key = key
            centre = np.array([x, y, z], dtype=float)
            if radius:  # the ball's centre lies back along the turned press axis
                centre = tip_centres_mm(centre, np.asarray(self._quaternion), (0.0, 0.0, 0.0),
                                        radius)
            if self.setup.in_gap(centre):
                self._depth, self._normal, self._z = 0.0, np.zeros(3), float(centre[2])
            else:
                p = self.params
                found = contact(self.setup.part, centre, self.setup.tip_radius_mm,
                                p.thickness_mm)
                sunk = p.set_mm * (1.0 - np.exp(-self.passes / p.set_passes))
                depth = float(found.depth_mm) - float(sunk)
                inside = np.isfinite(depth) and 0 < depth <= p.thickness_mm + WALL_MM
                self._depth = depth if inside else 0.0
                self._normal = np.asarray(found.normal, dtype=float)
                self._z = float(centre[2])
        return self._depth, self._normal, self._z

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        """The reaction force (3,) in N, world frame, on the tool at ``position_mm``."""
        depth, normal, z = self._contact(position_mm)
        if depth <= 0.0:
            return np.zeros(3)
        p = self.params
        force = float(normal_force_n(p, float(self.passes), depth, z, self.relaxing_mm,
                                     self.hysteresis_state))
        if p.friction_coefficient != 0.0 and any(self.slide_direction):
            return np.asarray(force * normal - p.friction_coefficient * force
                              * np.asarray(self.slide_direction), dtype=float)
        return np.asarray(force * normal, dtype=float)

    def evolve(self, position_mm: np.ndarray, dt_s: float) -> None:
        """Advance the relaxation over ``dt_s`` (the depth taken to change linearly)."""
        p = self.params
        depth, _, _ = self._contact(position_mm)
        foam = elastic_depth_mm(p, min(depth, p.thickness_mm))
        change, self._foam_mm = foam - self._foam_mm, foam
        if p.relaxation_ratio == 0.0 or dt_s <= 0.0:
            self.relaxing_mm = 0.0
            return
        self.relaxing_mm = relaxation_step(p, self.relaxing_mm, change, dt_s)
        if foam == 0.0:
            self.relaxing_mm = 0.0  # out of contact the foam recovers freely

    def observe_pose(self, position_mm: np.ndarray) -> None:
        """Note where the tool is; a pass ends when it leaves the foam after touching it."""
        depth, normal, _ = self._contact(position_mm)
        p = self.params
        if p.hysteresis_loss != 0.0 or p.friction_coefficient != 0.0:
            self._follow_move(position_mm, depth, normal)
        if depth > 0.0:
            self._touched = True
        elif self._touched:
            self.passes += 1
            self._touched = False

    def _follow_move(self, position_mm: np.ndarray, depth_mm: float, normal: np.ndarray) -> None:
        """Bring the hysteresis state and the last slide to a reported pose (as the sponge's)."""
        p = self.params
        arrived = self._arrive(position_mm, depth_mm)
        if arrived is None:  # off the foam: it forgets its branch, nothing holds its skin
            return
        here, last = arrived
        along_mm, direction = 0.0, None
        if last is not None and last != here:
            move = np.subtract(here, last)
            along = move - float(move @ normal) * normal  # the slide along the part
            length = float(np.linalg.norm(along))
            if slides(length, float(np.linalg.norm(move))):
                along_mm, direction = length, along / length
        if p.hysteresis_loss != 0.0:
            foam = min(depth_mm, p.thickness_mm)
            self.hysteresis_state = hysteresis_step(
                p, self.hysteresis_state, foam - self._hysteresis_foam_mm, along_mm)
            self._hysteresis_foam_mm = foam
        if p.friction_coefficient != 0.0 and direction is not None:
            self.slide_direction = (float(direction[0]), float(direction[1]),
                                    float(direction[2]))

    def state_dict(self) -> State:
        """The state to checkpoint (plain numbers; the sponge's keys and the tool's orientation)."""
        w, x, y, z = self._quaternion
        return {**self._memory_state(), "qw": w, "qx": x, "qy": y, "qz": z}

    def load_state_dict(self, state: State) -> None:
        """Restore :meth:`state_dict`."""
        self._load_memory(state)
        self._quaternion = (float(state.get("qw", 1.0)), float(state.get("qx", 0.0)),
                            float(state.get("qy", 0.0)), float(state.get("qz", 0.0)))
        self._key = None
