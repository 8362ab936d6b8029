"""The tool on the sensor: a roller on a holder, its mass and where it touches.

Description
-----------
The tool is rigid and fixed to the sensor, so its centre of mass and its
contact point are constant vectors in the sensor frame and rotate with the
flange. The sensor feels the tool's weight and the contact force moved to its
origin:

=================  ==========================================================
gravity force      ``F_g = R^T (0, 0, -m g)`` N, sensor frame
gravity moment     ``c x F_g`` N*m, with ``c`` the centre of mass in m
contact force      ``F_c = R^T f_world`` N, sensor frame
contact moment     ``p x F_c`` N*m, with ``p`` the contact point in m
=================  ==========================================================

``R`` maps the sensor frame to the world frame (z up, gravity -z). A
calibration tool fits ``m`` and ``m c`` from static poses (10-parameter least
squares), which is why they are parameters here and nothing else reads them.

Defaults: a 0.9 kg roller and holder, centre of mass 60 mm out along the
sensor z axis, roller contact point 150 mm out: typical of a small roller tool
on a JR3 67M25 class sensor (weight 8.8 N, well under a 200 N full scale).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from forcelearn.devices import STANDARD_GRAVITY_M_S2 as STANDARD_GRAVITY_M_S2  # re-exported

MM_PER_M = 1000.0


@dataclass(frozen=True)
class ToolParams:
    """Mass (kg), centre of mass and contact point (mm, sensor frame) of the tool."""

    mass_kg: float = 0.9
    com_mm: tuple[float, float, float] = (0.0, 0.0, 60.0)
    contact_point_mm: tuple[float, float, float] = (0.0, 0.0, 150.0)

    def __post_init__(self) -> None:
        if self.mass_kg < 0:
            raise ValueError(f"tool mass_kg must be >= 0, got {self.mass_kg}")


POINT_TOOL = ToolParams(mass_kg=0.0, com_mm=(0.0, 0.0, 0.0), contact_point_mm=(0.0, 0.0, 0.0))
"""A massless tool touching at the sensor origin (no gravity, no moments)."""


def _wrench(point_mm: tuple[float, float, float], force: np.ndarray) -> np.ndarray:
    """Return (F, r x F) for a force (3,) in N acting at ``point_mm`` (written out: hot path)."""
    rx, ry, rz = (c / MM_PER_M for c in point_mm)
    fx, fy, fz = (float(v) for v in force)
    return np.array([fx, fy, fz, ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx])


def gravity_wrench(tool: ToolParams, rotation: np.ndarray) -> np.ndarray:
    """Return the tool's weight as a wrench (6,) in the sensor frame, N and N*m."""
    force = rotation.T @ np.array([0.0, 0.0, -tool.mass_kg * STANDARD_GRAVITY_M_S2])
    return _wrench(tool.com_mm, force)


def contact_wrench(tool: ToolParams, rotation: np.ndarray, force_world_n: np.ndarray) -> np.ndarray:
    """Return a contact force at the tool's contact point as a sensor-frame wrench (6,)."""
    force = rotation.T @ np.asarray(force_world_n, dtype=float)
    return _wrench(tool.contact_point_mm, force)
