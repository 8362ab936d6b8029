"""The tool on the sensor: a roller on a holder, its mass, where it touches, how the sensor sits.

Description
-----------
The tool is rigid and fixed to the sensor, and the sensor to the robot's
flange, so the centre of mass and the contact point are constant vectors in
the sensor frame and rotate with the flange. The robot reports the flange's
orientation ``R_f`` (flange frame -> world); the sensor frame sits on the
flange turned by the mounting rotation ``R_m`` (sensor frame -> flange frame),
so the sensor frame maps to the world by ``R = R_f R_m``. The sensor feels the
tool's weight and the contact force moved to its origin:

=================  ==========================================================
gravity force      ``F_g = R^T (0, 0, -m g)`` N, sensor frame
gravity moment     ``c x F_g`` N*m, with ``c`` the centre of mass in m
contact force      ``F_c = R^T f_world`` N, sensor frame
contact moment     ``p x F_c`` N*m, with ``p`` the contact point in m
=================  ==========================================================

World frame z up, gravity -z. A calibration tool fits ``m``, ``m c`` and
``R_m`` from static poses, which is why they are parameters here and nothing
else reads them. ``[emulator.tool]`` of a cell config sets them
(:mod:`forcelearn.site.emulated_tool` checks them against the sensor's range).

Defaults: a 0.9 kg roller and holder, centre of mass 60 mm out along the
sensor z axis, roller contact point 150 mm out, the sensor's axes those of the
flange: typical of a small roller tool on a JR3 67M25 class sensor (weight
8.8 N, well under a 200 N full scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from forcelearn.devices import IDENTITY_QUATERNION, quaternion_to_matrix
from forcelearn.devices import STANDARD_GRAVITY_M_S2 as STANDARD_GRAVITY_M_S2  # re-exported

MM_PER_M = 1000.0


@dataclass(frozen=True)
class ToolParams:
    """Mass (kg), centre of mass and contact point (mm, sensor frame), sensor mounting.

    ``mounting_quaternion`` (w, x, y, z) turns the sensor frame into the flange
    frame (identity: the sensor's axes are the flange's).
    """

    mass_kg: float = 0.9
    com_mm: tuple[float, float, float] = (0.0, 0.0, 60.0)
    contact_point_mm: tuple[float, float, float] = (0.0, 0.0, 150.0)
    mounting_quaternion: tuple[float, float, float, float] = IDENTITY_QUATERNION

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_kg) and self.mass_kg >= 0):
            raise ValueError(f"tool mass_kg must be finite and >= 0, got {self.mass_kg}")
        norm = math.sqrt(sum(c * c for c in self.mounting_quaternion))
        if len(self.mounting_quaternion) != 4 or abs(norm - 1.0) > 1e-6:
            raise ValueError(f"tool mounting_quaternion must be a unit quaternion (w, x, y, z), "
                             f"got {self.mounting_quaternion}")

    @property
    def mounting(self) -> np.ndarray | None:
        """R_m (3x3, sensor frame -> flange frame), or None for the identity (the hot path)."""
        if self.mounting_quaternion == IDENTITY_QUATERNION:
            return None
        return quaternion_to_matrix(self.mounting_quaternion)


POINT_TOOL = ToolParams(mass_kg=0.0, com_mm=(0.0, 0.0, 0.0), contact_point_mm=(0.0, 0.0, 0.0))
"""A massless tool touching at the sensor origin (no gravity, no moments)."""


def sensor_rotation(tool: ToolParams, flange_rotation: np.ndarray) -> np.ndarray:
    """Return R = R_f R_m (sensor frame -> world) for the flange's rotation R_f (3x3)."""
    mounting = tool.mounting
    return flange_rotation if mounting is None else flange_rotation @ mounting


def _wrench(point_mm: tuple[float, float, float], force: np.ndarray) -> np.ndarray:
    """Return (F, r x F) for a force (3,) in N acting at ``point_mm`` (written out: hot path)."""
    rx, ry, rz = point_mm[0] / MM_PER_M, point_mm[1] / MM_PER_M, point_mm[2] / MM_PER_M
    fx, fy, fz = force.tolist()
    return np.array([fx, fy, fz, ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx])


def gravity_wrench(tool: ToolParams, rotation: np.ndarray) -> np.ndarray:
    """Return the tool's weight as a wrench (6,) in the sensor frame, N and N*m.

    ``rotation`` is the flange's (3x3, flange frame -> world); the mounting is applied here.
    """
    force = sensor_rotation(tool, rotation).T @ np.array(
        [0.0, 0.0, -tool.mass_kg * STANDARD_GRAVITY_M_S2])
    return _wrench(tool.com_mm, force)


def contact_wrench(tool: ToolParams, rotation: np.ndarray, force_world_n: np.ndarray) -> np.ndarray:
    """Return a contact force at the tool's contact point as a sensor-frame wrench (6,).

    ``rotation`` is the flange's (3x3, flange frame -> world).
    """
    force = sensor_rotation(tool, rotation).T @ np.asarray(force_world_n, dtype=float)
    return _wrench(tool.contact_point_mm, force)
