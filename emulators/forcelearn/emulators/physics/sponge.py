"""The emulated sponge of the paper's §5: the foam strip with its state, for the cell physics.

The law (the force on a tool point, its parameters, units and defaults) is
:mod:`forcelearn.emulators.physics.sponge_law`, whose docstring is the full
reference; the twin's forward model calls the same functions over arrays.
This module adds what changes as the cell runs (:class:`Sponge`): the pass
count, the standard linear solid's relaxing part q, the Dahl hysteresis state
s and the direction of the roller's last slide, each brought up to date from
the poses the robot emulator reports and the motion grid's ticks.

The law's names are importable from here too (the cell configs' and the
tests' one place for the sponge).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from forcelearn.emulators.physics.arm_motion import PoseKey
from forcelearn.emulators.physics.foam_memory import FoamMemory, State
from forcelearn.emulators.physics.sponge_law import (
    SLIDE_MIN_FRACTION,
    SpongeParams,
    along_surface_mm,
    contact_force_n,
    depth_for_force_mm,
    direction_terms,
    elastic_depth_mm,
    hysteresis_step,
    normal_force_n,
    penetration_mm,
    point_contact_force_n,
    point_penetration_mm,
    relaxation_step,
    set_depth_mm,
    slide_direction,
    slides,
    stiffness_n_per_mm,
    surface_dy_dz,
    surface_normal,
    surface_y_mm,
)
from forcelearn.emulators.physics.tick_runs import ticks_by_length

__all__ = [
    "SLIDE_MIN_FRACTION", "Sponge", "SpongeParams", "contact_force_n", "depth_for_force_mm",
    "elastic_depth_mm", "hysteresis_step", "normal_force_n", "penetration_mm",
    "relaxation_step", "slide_direction", "slides", "stiffness_n_per_mm", "surface_dy_dz",
    "surface_normal", "surface_y_mm",
]


class Sponge(FoamMemory):
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
        super().__init__(passes)
        self._memo_key: tuple[float, ...] | None = None
        self._memo_force = np.zeros(3)
        self._memo_values = (0.0, 0.0, 0.0)
        """``_memo_force`` as floats (:meth:`contact_force_world_values`)."""
        self._direction_key: tuple[SpongeParams, float] | None = None
        self._direction_terms = (np.zeros(3), np.ones(()))
        self._depth_key: tuple[float, ...] | None = None
        self._depth_mm = 0.0
        self._set_key: tuple[SpongeParams, int] | None = None
        self._set_mm = 0.0
        self._relax_terms = (-1.0, -1.0, 0.0, 0.0, 0.0)
        """(relaxation time s, dt s, keep, time / dt, 1 - keep) of :func:`relaxation_step`."""

    accepts_point_tuple = True
    """:meth:`observe_pose`, :meth:`evolve` and :meth:`contact_force_world_n` take the
    position as a tuple of floats too (what :class:`~.cell.CellPhysics` hands over on every
    motion tick and sensor sample: no array built)."""

    def _penetration_mm(self, position_mm: np.ndarray | tuple[float, float, float]) -> float:
        """:func:`penetration_mm` at the present pass count, remembered for the last position."""
        passes = self.passes
        if type(position_mm) is tuple:
            key = (passes, position_mm[1], position_mm[2])
        else:
            key = (passes, float(position_mm[1]), float(position_mm[2]))
        if key != self._depth_key:  # asked once per pose and once per motion tick
            self._depth_key = key
            p = self.params
            if (p, passes) != self._set_key:  # the set changes once per pass
                self._set_key = (p, passes)
                self._set_mm = set_depth_mm(p, passes)
            self._depth_mm = point_penetration_mm(p, self._set_mm, key[1], key[2])
        return self._depth_mm

    def contact_force_world_n(
        self, position_mm: np.ndarray | tuple[float, float, float]
    ) -> np.ndarray:
        """Return the reaction force (3,) in N, world frame, at the present pass count."""
        self._memo(position_mm)
        return self._memo_force.copy()

    def contact_force_world_values(
        self, position_mm: np.ndarray | tuple[float, float, float]
    ) -> tuple[float, float, float]:
        """:meth:`contact_force_world_n` as three floats (its ``tolist``), no array copied.

        A force law overridden by a subclass or wrapped on the object (a test's recorder)
        is asked itself.
        """
        if ("contact_force_world_n" in self.__dict__
                or type(self).contact_force_world_n is not Sponge.contact_force_world_n):
            return tuple(self.contact_force_world_n(position_mm).tolist())
        self._memo(position_mm)
        return self._memo_values

    def _memo(self, position_mm: np.ndarray | tuple[float, float, float]) -> None:
        """Bring the remembered force to ``position_mm`` and the present state."""
        coords = position_mm.tolist() if isinstance(position_mm, np.ndarray) else position_mm
        key = (self.passes, self.relaxing_mm, self.hysteresis_state, *self.slide_direction,
               *coords)  # tuples compare by value: 1 == 1.0, so no float() is needed
        if key != self._memo_key:  # the sensor asks thousands of times per pose
            self._memo_key = key
            # contact_force_n of the point: its depth as remembered, the surface's direction
            # and length kept per height (the same functions, to the bit)
            depth = self._penetration_mm(position_mm)
            if depth <= 0.0:  # point_contact_force_n's answer out of contact, no direction
                self._memo_force, self._memo_values = np.zeros(3), (0.0, 0.0, 0.0)
                return
            p, z = self.params, float(coords[2])
            if (p, z) != self._direction_key:
                self._direction_key = (p, z)
                self._direction_terms = direction_terms(p, z)
            self._memo_force = point_contact_force_n(
                p, self.passes, depth, z, self.relaxing_mm, self.hysteresis_state,
                self.slide_direction, *self._direction_terms)
            self._memo_values = tuple(self._memo_force.tolist())  # type: ignore[assignment]

    def evolve(self, position_mm: np.ndarray | tuple[float, float, float], dt_s: float) -> None:
        """Advance the relaxation over ``dt_s`` during which the tool moved to ``position_mm``.

        The elastic depth is taken to change linearly over the interval (exact
        for the standard linear solid under a ramp).
        """
        self._evolve_at(self._penetration_mm(position_mm), dt_s)

    def tick(self, position_mm: tuple[float, float, float], dt_s: float, moved: bool) -> None:
        """One motion tick: :meth:`observe_pose` if the tool ``moved``, then :meth:`evolve`.

        The same state changes in the same order, the depth found once (the cell's hot
        path: about 200 ticks per Surface-v0 step).
        """
        depth = self._penetration_mm(position_mm)
        if moved and self._observe_at(position_mm, depth):
            depth = self._penetration_mm(position_mm)  # at the new pass count
        self._evolve_at(depth, dt_s)

    def ticks(self, keys: Sequence[PoseKey], dt_s: float, before: PoseKey) -> PoseKey:
        """:meth:`tick` for each tool key in turn, ``dt_s`` each; returns the last key recorded.

        A key that differs from the last one recorded (at first ``before``) is a tick
        the tool moved on (it is then recorded); an equal one evolves at the recorded
        position, as :class:`~.cell.CellPhysics` hands positions to :meth:`tick`. For a
        linear foam without hysteresis or friction (the default) the loop is written out
        in one function: the same operations in the same order, to the bit
        (tests/emulators/physics/test_cell_tick.py); otherwise :meth:`tick` per key.
        """
        p = self.params
        if (type(self) is not Sponge or p.hysteresis_loss != 0.0 or p.friction_coefficient != 0.0
                or p.stiffening_exponent != 1.0 or p.relaxation_ratio == 0.0 or dt_s <= 0.0):
            tick = self.tick
            for key in keys:
                if key != before:
                    before = key
                    tick((key[0], key[1], key[2]), dt_s, True)
                else:
                    tick((before[0], before[1], before[2]), dt_s, False)
            return before
        # the terms of _evolve_at at this (relaxation time, dt)
        terms = self._relax_terms
        if terms[0] != p.relaxation_time_s or terms[1] != dt_s:
            keep = math.exp(-dt_s / p.relaxation_time_s)
            self._relax_terms = terms = (p.relaxation_time_s, dt_s, keep,
                                         p.relaxation_time_s / dt_s, 1.0 - keep)
        keep, ratio, gain = terms[2], terms[3], terms[4]
        # point_penetration_mm's constants (params are frozen)
        bottom, top, thickness = p.z_bottom_mm, p.z_top_mm, p.thickness_mm
        waviness, wavelength = p.waviness_mm, p.waviness_wavelength_mm
        surface_y, slope = p.surface_y_mm, p.surface_slope
        sin, two_pi = math.sin, 2 * math.pi
        passes = self.passes
        if (p, passes) != self._set_key:
            self._set_key = (p, passes)
            self._set_mm = set_depth_mm(p, passes)
        set_mm = self._set_mm
        depth_key, depth = self._depth_key, self._depth_mm
        # the memo's key in three locals (compared one by one: the same answer as the tuple)
        key_passes: Any
        key_y: Any
        key_z: Any
        key_passes, key_y, key_z = depth_key if depth_key is not None else (None, None, None)
        foam_mm, relaxing = self._foam_mm, self.relaxing_mm
        touched = self._touched
        y, z = before[1], before[2]
        # the surface's y at (pass count, z): kept while neither changes (a press moves in y)
        surface_passes: int | None = None
        surface_z = surface = 0.0
        on_strip = False
        for key in keys:
            moved = key != before
            if moved:
                before = key
                y, z = key[1], key[2]
            # _penetration_mm((x, y, z)); max(0.0, d) and min(a, b) written as comparisons
            if y != key_y or z != key_z or passes != key_passes:
                key_passes, key_y, key_z = passes, y, z
                if z != surface_z or passes != surface_passes:
                    surface_passes, surface_z, on_strip = passes, z, bottom <= z <= top
                    if on_strip:
                        travelled = top - z
                        wave = waviness * sin(two_pi * travelled / wavelength)
                        surface = surface_y + slope * travelled + wave - set_mm
                depth = 0.0
                if on_strip and surface - y > 0.0:
                    depth = surface - y
            if moved:  # _observe_at
                if depth > 0.0:
                    touched = True
                elif touched:
                    passes += 1  # finish_pass
                    touched = False
                    self._set_key = (p, passes)
                    self._set_mm = set_mm = set_depth_mm(p, passes)
                    key_passes, key_y, key_z = passes, y, z
                    surface_passes, surface_z, on_strip = passes, z, bottom <= z <= top
                    if on_strip:
                        travelled = top - z
                        wave = waviness * sin(two_pi * travelled / wavelength)
                        surface = surface_y + slope * travelled + wave - set_mm
                    depth = 0.0
                    if on_strip and surface - y > 0.0:
                        depth = surface - y
            # _evolve_at(depth, dt_s)
            foam = thickness if thickness < depth else depth
            change, foam_mm = foam - foam_mm, foam
            relaxing = relaxing * keep + change * ratio * gain
            if foam == 0.0 and relaxing > 0.0:
                relaxing = 0.0
        self.passes, self._touched = passes, touched
        if key_passes is not None:
            self._depth_key, self._depth_mm = (key_passes, key_y, key_z), depth
        self._foam_mm, self.relaxing_mm = foam_mm, relaxing
        return before

    def ticks_seen(
        self, runs: Sequence[tuple[Sequence[PoseKey], float, tuple[float, float, float] | None]],
        before: PoseKey,
    ) -> PoseKey:
        """For each ``(keys, dt_s, seen)``: :meth:`ticks`, then :meth:`observe_pose` of ``seen``.

        ``seen`` (None: none) is where the last key recorded has the tool: a reached pose
        reported again after the ticks that moved the tool there (the cell publishing it).
        Returns the last key recorded. On a foam whose observation only marks contact and
        counts passes (no hysteresis, no friction: :class:`Sponge` itself), such a second
        observation changes nothing unless that tick ended a pass (the same depth at the same
        pass count), so the keys run in as few :meth:`ticks` calls as their ``dt_s`` allow;
        if a pass ends meanwhile, the state is restored and the runs taken one by one. The
        same state to the bit as one by one (tests/emulators/physics/test_cell_rest.py).
        """
        p = self.params
        if type(self) is Sponge and p.hysteresis_loss == 0.0 and p.friction_coefficient == 0.0:
            saved, passes = self.state_dict(), self.passes
            recorded = ticks_by_length(self, ((keys, dt) for keys, dt, _ in runs), before)
            if self.passes == passes:
                return recorded
            self.load_state_dict(saved)
        recorded = before
        for run_keys, run_dt, seen in runs:
            if run_keys:
                recorded = self.ticks(run_keys, run_dt, recorded)
            if seen is not None:
                self.observe_pose(seen)
        return recorded

    def _evolve_at(self, depth_mm: float, dt_s: float) -> None:
        """:meth:`evolve` with the tool ``depth_mm`` deep (mm, at the present pass count)."""
        p = self.params
        depth = min(depth_mm, p.thickness_mm)
        # elastic_depth_mm is the depth itself for a linear foam: not called on every tick
        foam = depth if p.stiffening_exponent == 1.0 else elastic_depth_mm(p, depth)
        change, self._foam_mm = foam - self._foam_mm, foam
        if p.relaxation_ratio == 0.0 or dt_s <= 0.0:
            self.relaxing_mm = 0.0
            return
        # relaxation_step(p, q, change, dt_s) with its terms kept per (time, dt): the same
        # operations in the same order, to the bit (tests/emulators/physics/test_sponge_law.py)
        terms = self._relax_terms
        if terms[0] != p.relaxation_time_s or terms[1] != dt_s:
            keep = math.exp(-dt_s / p.relaxation_time_s)
            self._relax_terms = terms = (p.relaxation_time_s, dt_s, keep,
                                         p.relaxation_time_s / dt_s, 1.0 - keep)
        self.relaxing_mm = self.relaxing_mm * terms[2] + change * terms[3] * terms[4]
        if foam == 0.0 and self.relaxing_mm > 0.0:
            self.relaxing_mm = 0.0  # out of contact the foam recovers freely

    def observe_pose(self, position_mm: np.ndarray | tuple[float, float, float]) -> None:
        """Note where the tool is; completes a pass when it leaves the sponge after contact."""
        self._observe_at(position_mm, self._penetration_mm(position_mm))

    def _observe_at(
        self, position_mm: np.ndarray | tuple[float, float, float], depth_mm: float
    ) -> bool:
        """:meth:`observe_pose` with the tool ``depth_mm`` deep; True when it finished a pass."""
        p = self.params
        if p.hysteresis_loss != 0.0 or p.friction_coefficient != 0.0:
            self._follow_move(position_mm, depth_mm)
        if depth_mm > 0.0:
            self._touched = True
            return False
        if self._touched:
            self.finish_pass()
            return True
        return False

    def _follow_move(
        self, position_mm: np.ndarray | tuple[float, float, float], depth_mm: float
    ) -> None:
        """Bring the hysteresis state and the last slide to a reported pose."""
        p = self.params
        arrived = self._arrive(position_mm, depth_mm)
        if arrived is None:  # off the foam: it forgets its branch, nothing holds its skin
            return
        here, last = arrived
        move = np.subtract(here, last) if last is not None and last != here else None
        along_mm = 0.0  # travel along the surface; a press within ~6 degrees of the normal: none
        if move is not None:
            along_mm = float(np.linalg.norm(along_surface_mm(p, move, here[2])))
            if not slides(along_mm, float(np.linalg.norm(move))):
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

    def state_dict(self) -> State:
        """Return the state to checkpoint (plain numbers)."""
        return self._memory_state()

    def load_state_dict(self, state: State) -> None:
        """Restore a state from :meth:`state_dict` (keys it lacks take their fresh values)."""
        self._load_memory(state)
