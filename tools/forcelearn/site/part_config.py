"""``[task] kind = "path"`` and ``[emulator.part]`` of a cell config (docs/path.md).

``[emulator.part]`` takes the part's keys (:mod:`forcelearn.emulators.physics.part_table`:
``shape`` and the shape's own) and three of the tool's contact with it:

=================  =========================================================
``tip_radius_mm``  radius of the tool's tip (roller or pad across its contact), mm
``gap_min_mm``     with ``gap_max_mm``: a box (world frame, mm) cut out of the part
``gap_max_mm``     (no foam, no contact inside: a slot a taught path crosses)
=================  =========================================================

The foam on the part is ``[emulator.sponge]``'s (thickness, stiffness, wear,
relaxation); its hysteresis and friction follow a slide along the §5 strip and
are refused with a part.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from forcelearn.emulators.physics.part_foam import PartSetup
from forcelearn.emulators.physics.part_table import part_from_table
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.errors import ConfigError
from forcelearn.tasks.path_spec import PathTaskSpec, build_path_task, task_kind

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
    if sponge.hysteresis_loss != 0.0 or sponge.friction_coefficient != 0.0:
        raise ConfigError("emulator.sponge.hysteresis_loss and friction_coefficient are not "
                          "modelled on a part ([emulator.part]): leave them at 0")
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


def filter_keys(spec: PathTaskSpec | None, table: Mapping[str, Any]) -> dict[str, Any]:
    """``[filter]`` over the path task's defaults (:func:`path_filter_defaults`)."""
    return {**path_filter_defaults(spec), **table}


def path_filter_defaults(spec: PathTaskSpec | None) -> dict[str, Any]:
    """``[filter]`` defaults of the path task: the normal force is minus the force axis's.

    The part pushes back against the tool's press, so along a tool axis the
    pressing force reads negative; ``axis`` is the sensor axis the force axis
    is (a straight mounting: sensor axes = tool axes). A force axis that is
    not a tool axis is refused (the filter reads one axis).
    """
    if spec is None:
        return {}
    axis = [round(c, 9) for c in spec.force_axis]
    for index in range(3):
        if abs(abs(axis[index]) - 1.0) < 1e-9:
            return {"axis": index, "sign": -1.0 if axis[index] > 0 else 1.0}
    raise ConfigError(f"task.force_axis = {list(spec.force_axis)}: the force filter reads one "
                      "sensor axis; give a tool axis, e.g. [0, 0, 1] (tool z) or [1, 0, 0]")
