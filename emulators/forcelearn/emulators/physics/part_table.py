"""An emulated part from its TOML table (``[emulator.part]``), keys checked by name.

=============  ==============================================================
``shape``      ``"plane"``, ``"cylinder"``, ``"sphere"`` or ``"heightmap"``
plane          ``point_mm``, ``normal``
cylinder       ``point_mm`` (on the axis), ``axis``, ``radius_mm``, ``concave``
sphere         ``centre_mm``, ``radius_mm``, ``concave``
heightmap      ``file`` (CSV or .npy, relative to the config file),
               ``origin_mm``, ``spacing_mm``, ``normal``, ``u_axis``,
               ``interpolation``
=============  ==============================================================

The cell config reads ``[emulator.part]`` through :func:`part_from_table`
(``forcelearn.site.part_config``, which adds the tool's tip and a gap).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from forcelearn.emulators.physics.part import (
    Cylinder,
    Heightmap,
    Part,
    Plane,
    Sphere,
    load_heights,
)
from forcelearn.errors import ConfigError

SHAPES: dict[str, tuple[type[Plane | Cylinder | Sphere | Heightmap], set[str], set[str]]] = {
    "plane": (Plane, {"point_mm", "normal"}, set()),
    "cylinder": (Cylinder, {"point_mm", "axis", "radius_mm"}, {"concave"}),
    "sphere": (Sphere, {"centre_mm", "radius_mm"}, {"concave"}),
    "heightmap": (Heightmap, {"file", "origin_mm", "spacing_mm"},
                  {"normal", "u_axis", "interpolation"}),
}
"""Each shape: its class, required keys and optional keys."""


def part_from_table(table: Mapping[str, Any], config_dir: str | Path | None = None,
                    section: str = "emulator.part") -> Part:
    """The part a ``[emulator.part]`` table describes; a ConfigError names ``section.key``."""
    values = dict(table)
    shape = values.pop("shape", None)
    if shape not in SHAPES:
        raise ConfigError(f"{section}.shape = {shape!r}: must be one of {', '.join(SHAPES)}")
    cls, required, optional = SHAPES[shape]
    missing = sorted(required - set(values))
    unknown = sorted(set(values) - required - optional)
    if missing or unknown:
        raise ConfigError(
            f"[{section}] shape {shape!r}: "
            + "; ".join(part for part in (
                f"missing {', '.join(f'{section}.{k}' for k in missing)}" if missing else "",
                f"unknown {', '.join(f'{section}.{k}' for k in unknown)}" if unknown else "",
            ) if part)
            + f" (its keys: {', '.join(sorted(required | optional))})"
        )
    for key, value in values.items():
        if key in ("concave",) and not isinstance(value, bool):
            raise ConfigError(f"{section}.{key} = {value!r}: true or false")
        if key.endswith(("_mm", "normal", "axis")) and key not in ("radius_mm", "spacing_mm"):
            if not (isinstance(value, list | tuple) and len(value) == 3
                    and all(isinstance(v, int | float) and not isinstance(v, bool)
                            for v in value)):
                raise ConfigError(f"{section}.{key} = {value!r}: must be 3 numbers")
            values[key] = tuple(float(v) for v in value)
    if shape == "heightmap":
        file = Path(values.pop("file"))
        if config_dir is not None and not file.is_absolute():
            file = Path(config_dir) / file
        try:
            values["heights_mm"] = load_heights(file)
        except ValueError as exc:
            raise ConfigError(f"{section}.file: {exc}") from exc
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"[{section}] {exc}") from exc
