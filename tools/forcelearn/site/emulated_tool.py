"""``[emulator.tool]``: the emulated tool's mass, centre of mass, contact point and mounting.

::

    [emulator.tool]
    mass_kg = 2.4                          # kg, > 0 (0: no tool)
    com_mm = [35.0, -20.0, 80.0]           # centre of mass, sensor frame, mm
    contact_point_mm = [0.0, 0.0, 180.0]   # where the tool touches, sensor frame, mm
    mounting_rpy_deg = [0.0, 0.0, 30.0]    # sensor frame against the flange: roll x, pitch y,
                                           # yaw z, deg, fixed axes (R = Rz Ry Rx, RAPID OrientZYX)
    # or: mounting_quaternion = [w, x, y, z]  (sensor frame -> flange frame, as RAPID orient)

Every key is optional; the table's absence leaves the default tool
(:class:`~forcelearn.emulators.physics.tool.ToolParams`: 0.9 kg, (0, 0, 60) mm).
Refused at load, naming the key, when beyond what a tool on this sensor can
be (docs/calibration.md, "The emulated tool"): a mass below 0 or whose weight
exceeds the sensor's readable force on its strongest axis; a centre of mass or
contact point more than 2 m out; a gravity moment m g |c| beyond the
strongest moment axis's readable range; a mounting given twice, or not a
rotation.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from forcelearn.devices import STANDARD_GRAVITY_M_S2
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.netft.sensor_model import NetFtModelParams
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.errors import ConfigError

SECTION = "emulator.tool"
KEYS = ("mass_kg", "com_mm", "contact_point_mm", "mounting_rpy_deg", "mounting_quaternion")
MAX_REACH_MM = 2000.0
"""Largest coordinate of a centre of mass or contact point (mm), as in a calibration file."""
JR3_READABLE = 2.0
"""A JR3 counts to twice its full scale (int16 at 16384 counts per full scale)."""


def readable_range(model: Jr3ModelParams | NetFtModelParams) -> np.ndarray:
    """What the emulated sensor can read per axis before it saturates (N, N*m)."""
    if isinstance(model, NetFtModelParams):
        return np.asarray(model.ranges, dtype=float) * model.saturation_fraction
    return np.asarray(model.full_scales, dtype=float) * JR3_READABLE


def rpy_to_quaternion(rpy_deg: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of roll x, pitch y, yaw z (deg) about fixed axes: Rz Ry Rx."""
    x, y, z, w = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_quat()
    return (float(w), float(x), float(y), float(z))


def mounting_rpy_deg(quaternion: tuple[float, float, float, float]) -> tuple[float, ...]:
    """Roll x, pitch y, yaw z (deg, fixed axes) of a quaternion (w, x, y, z)."""
    w, x, y, z = quaternion
    return tuple(float(a) for a in Rotation.from_quat((x, y, z, w)).as_euler("xyz", degrees=True))


def _vector(table: dict[str, Any], key: str, size: int,
            section: str = SECTION) -> tuple[float, ...] | None:
    if key not in table:
        return None
    value = table[key]
    if (not isinstance(value, list | tuple) or len(value) != size
            or not all(isinstance(c, int | float) and not isinstance(c, bool)
                       and math.isfinite(c) for c in value)):
        raise ConfigError(f"{section}.{key} = {value!r}: must be {size} finite numbers")
    return tuple(float(c) for c in value)


def load_mounting(table: dict[str, Any],
                  section: str = SECTION) -> tuple[float, float, float, float] | None:
    """``mounting_rpy_deg`` or ``mounting_quaternion`` of a table (w, x, y, z), or None."""
    rpy = _vector(table, "mounting_rpy_deg", 3, section)
    quaternion = _vector(table, "mounting_quaternion", 4, section)
    if rpy is not None and quaternion is not None:
        raise ConfigError(f"{section}: give mounting_rpy_deg or mounting_quaternion, not both")
    if quaternion is None:
        return rpy_to_quaternion((rpy[0], rpy[1], rpy[2])) if rpy is not None else None
    norm = math.sqrt(sum(c * c for c in quaternion))
    if abs(norm - 1.0) > 1e-3:
        raise ConfigError(f"{section}.mounting_quaternion = {list(quaternion)}: must be a unit "
                          f"quaternion (w, x, y, z), its norm is {norm:.4g}")
    w, x, y, z = (c / norm for c in quaternion)
    return (w, x, y, z)


def load_tool(table: dict[str, Any] | None,
              model: Jr3ModelParams | NetFtModelParams) -> ToolParams:
    """Build the emulated tool from ``[emulator.tool]``; ConfigError names the key."""
    if table is None:
        return ToolParams()
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(f'{SECTION}.{k}' for k in unknown)}; "
                          f"known keys of [{SECTION}]: {', '.join(KEYS)}")
    default = ToolParams()
    mass = table.get("mass_kg", default.mass_kg)
    if isinstance(mass, bool) or not isinstance(mass, int | float) or not math.isfinite(mass):
        raise ConfigError(f"{SECTION}.mass_kg = {mass!r}: must be a finite number of kg")
    com = _vector(table, "com_mm", 3) or default.com_mm
    contact = _vector(table, "contact_point_mm", 3) or default.contact_point_mm
    mounting = load_mounting(table) or default.mounting_quaternion
    check_tool(float(mass), com, contact, readable_range(model))
    return ToolParams(float(mass), com, contact, mounting)  # type: ignore[arg-type]


def check_tool(mass_kg: float, com_mm: tuple[float, ...], contact_mm: tuple[float, ...],
               readable: np.ndarray) -> None:
    """Refuse a tool this sensor cannot carry, naming the key and the bound."""
    weight = mass_kg * STANDARD_GRAVITY_M_S2
    most_force = float(readable[:3].max())
    if mass_kg < 0 or weight > most_force:
        raise ConfigError(
            f"{SECTION}.mass_kg = {mass_kg:g}: must be 0..{most_force / STANDARD_GRAVITY_M_S2:.3g} "
            f"kg: the weight may not exceed what the sensor reads on its strongest force axis "
            f"({most_force:g} N); pick a larger sensor model in [emulator.sensor]")
    for key, point in (("com_mm", com_mm), ("contact_point_mm", contact_mm)):
        if max(abs(c) for c in point) > MAX_REACH_MM:
            raise ConfigError(f"{SECTION}.{key} = {list(point)}: each coordinate within "
                              f"±{MAX_REACH_MM:g} mm (no robot wrist carries a tool further out)")
    moment = weight * float(np.linalg.norm(com_mm)) / 1000.0
    most_moment = float(readable[3:].max())
    if moment > most_moment:
        raise ConfigError(
            f"{SECTION}.com_mm = {list(com_mm)}: the tool's gravity moment m g |c| = {moment:.3g} "
            f"N*m exceeds what the sensor reads on its strongest moment axis ({most_moment:g} "
            f"N*m): bring the centre of mass closer or pick a larger sensor model")
