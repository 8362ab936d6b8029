"""``[task] kind = "path"`` and ``[emulator.part]`` of a cell config (docs/path.md).

``[emulator.part]`` takes the part's keys (:mod:`forcelearn.emulators.physics.part_table`:
``shape`` and the shape's own) and three of the tool's contact with it:

=================  =========================================================
``tip_radius_mm``  radius of the tool's tip (roller or pad across its contact), mm
``gap_min_mm``     with ``gap_max_mm``: a box (world frame, mm) cut out of the part
``gap_max_mm``     (no foam, no contact inside: a slot a taught path crosses)
=================  =========================================================

The foam on the part is ``[emulator.sponge]``'s (thickness, stiffness, wear,
relaxation, hysteresis, friction), on the part's normal
(:mod:`forcelearn.emulators.physics.part_foam`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.calibration import load_calibration
from forcelearn.devices import IDENTITY_QUATERNION, quaternion_to_matrix
from forcelearn.emulators.physics.part_foam import PartSetup
from forcelearn.emulators.physics.part_table import part_from_table
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.errors import ConfigError
from forcelearn.site.emulated_tool import load_mounting
from forcelearn.tasks.path_spec import PathTaskSpec, build_path_task, task_kind

Quaternion = tuple[float, float, float, float]

AXIS_SNAP_DEG = 1.0
"""A force axis this close to a sensor axis (deg) is read on that axis: the force along it is
then within cos 1 deg = 0.99985 of the whole (under a sensor's calibration accuracy), and an
estimated mounting of a straight sensor (``forcelearn calibrate``: within ~0.5 deg) stays
straight, so its runs read what they read before the mounting was known."""

__all__ = ["PartSetup", "PathTaskSpec", "filter_keys", "load_part", "load_path_task",
           "path_filter_defaults"]

SECTION = "emulator.part"
CONTACT_KEYS = ("tip_radius_mm", "gap_min_mm", "gap_max_mm")


def load_part(table: Mapping[str, Any] | None, sponge: SpongeParams,
              config_path: str | Path | None) -> PartSetup | None:
    """The part of ``[emulator.part]`` (None: no table), its tip and gap; errors name the key.

    ``file`` (a height map's) is relative to the config file at ``config_path``.
    """
    if table is None:
        return None
    config_dir = Path(config_path).parent if config_path else None
    if not isinstance(table, Mapping):
        raise ConfigError(f"{SECTION}: a table (shape = \"cylinder\" ...)")
    values = dict(table)
    contact = {key: values.pop(key) for key in CONTACT_KEYS if key in values}
    part = part_from_table(values, config_dir, SECTION)
    for key in ("gap_min_mm", "gap_max_mm"):
        corner = contact.get(key)
        if corner is not None:
            if not (isinstance(corner, list) and len(corner) == 3
                    and all(isinstance(v, int | float) and not isinstance(v, bool)
                            for v in corner)):
                raise ConfigError(f"{SECTION}.{key} = {corner!r}: must be 3 numbers (mm)")
            contact[key] = tuple(float(v) for v in corner)
    radius = contact.get("tip_radius_mm", 0.0)
    if isinstance(radius, bool) or not isinstance(radius, int | float):
        raise ConfigError(f"{SECTION}.tip_radius_mm = {radius!r}: a number of mm >= 0")
    try:
        return PartSetup(part, float(radius), contact.get("gap_min_mm"),
                         contact.get("gap_max_mm"))
    except ValueError as exc:
        raise ConfigError(f"[{SECTION}] {exc}") from exc


def load_path_task(table: Mapping[str, Any] | None, config_path: str | Path | None,
                   task_path: str | Path | None = None) -> PathTaskSpec | None:
    """The path task of ``[task]`` (None for the §5 task); ``task_path`` overrides its file.

    ``path`` is relative to the config file; ``task_path`` (``forcelearn run --path FILE``)
    as given, and makes the task the path task whatever ``[task] kind`` says.
    """
    table = dict(table or {})
    if task_path is None and task_kind(table) != "path":
        return None
    if task_path is not None:
        if task_kind(table) != "path":  # a §5 [task] table: --path replaces it
            table = {}
        table.update(kind="path", path=str(Path(task_path).resolve()))
    config_dir = Path(config_path).parent if config_path else None
    return build_path_task(table, config_dir)


def filter_keys(spec: PathTaskSpec | None, table: Mapping[str, Any],
                mounting: Quaternion | None = None) -> dict[str, Any]:
    """``[filter]`` over the path task's defaults (:func:`path_filter_defaults`).

    A ``[filter]`` that names its ``axis`` or ``sign`` reads that axis (no direction).
    """
    defaults = path_filter_defaults(spec, mounting)
    if "axis" in table or "sign" in table:
        defaults.pop("direction", None)
    return {**defaults, **table}


def path_filter_defaults(spec: PathTaskSpec | None,
                         mounting: Quaternion | None = None) -> dict[str, Any]:
    """``[filter]`` defaults of the path task: the normal force is minus the force axis's.

    The part pushes back against the tool's press, so along the force axis the
    pressing force reads negative. ``force_axis`` must be a tool axis (as FC
    Pressure's Fx, Fy, Fz). ``mounting`` (w, x, y, z; sensor frame ->
    flange frame, the calibration's) turns it into the sensor frame, ``R_m^T a``:
    when that is a sensor axis the filter reads that axis, else the component along
    it (``direction``). None: a straight mounting (sensor axes = tool axes). Within
    ``AXIS_SNAP_DEG`` of a sensor axis (an estimated mounting of a straight sensor) the
    filter reads that axis.
    """
    if spec is None:
        return {}
    axis = [round(c, 9) for c in spec.force_axis]
    tool = next((index for index in range(3) if abs(abs(axis[index]) - 1.0) < 1e-9), None)
    if tool is None:
        raise ConfigError(f"task.force_axis = {list(spec.force_axis)}: give a tool axis, e.g. "
                          "[0, 0, 1] (tool z) or [1, 0, 0] (FC Pressure's Fz or Fx)")
    if mounting is None or tuple(mounting) == IDENTITY_QUATERNION:
        return {"axis": tool, "sign": -1.0 if axis[tool] > 0 else 1.0}
    along = quaternion_to_matrix(mounting).T @ np.asarray(axis, dtype=float)
    nearest = int(np.argmax(np.abs(along)))
    if math.degrees(math.acos(min(1.0, abs(float(along[nearest]))))) <= AXIS_SNAP_DEG:
        return {"axis": nearest, "sign": -1.0 if along[nearest] > 0 else 1.0}
    unit = along / np.linalg.norm(along)
    return {"axis": nearest, "sign": -1.0,
            "direction": (float(unit[0]), float(unit[1]), float(unit[2]))}


def sensor_mounting(table: Mapping[str, Any], calibration_file: Path | None) -> Quaternion | None:
    """The sensor's mounting on the flange (w, x, y, z) the force axis is read through.

    The calibration file's (what compensates the readings), else ``[calibration]
    mounting_*`` (given), else None (straight).
    """
    if calibration_file is not None and calibration_file.is_file():
        return load_calibration(calibration_file).tool.mounting_quaternion
    return load_mounting(dict(table), "calibration")
