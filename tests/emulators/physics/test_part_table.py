"""[emulator.part] tables into parts, every key checked by name."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from forcelearn.emulators.physics.part import Cylinder, Heightmap, Plane, Sphere
from forcelearn.emulators.physics.part_table import part_from_table
from forcelearn.errors import ConfigError


def test_each_shape_from_its_table(tmp_path: Path) -> None:
    """The four shapes, a height map's file relative to the config's folder."""
    np.save(tmp_path / "h.npy", np.zeros((3, 4)))
    plane = part_from_table({"shape": "plane", "point_mm": [0, 0, 1], "normal": [0, 0, 2]})
    assert plane == Plane((0.0, 0.0, 1.0), (0.0, 0.0, 1.0))
    cylinder = part_from_table({"shape": "cylinder", "point_mm": [1, 2, 3], "axis": [0, 1, 0],
                                "radius_mm": 50, "concave": True})
    assert cylinder == Cylinder((1.0, 2.0, 3.0), (0.0, 1.0, 0.0), 50, concave=True)
    sphere = part_from_table({"shape": "sphere", "centre_mm": [0, 0, 0], "radius_mm": 5.5})
    assert sphere == Sphere((0.0, 0.0, 0.0), 5.5)
    heightmap = part_from_table({"shape": "heightmap", "file": "h.npy", "origin_mm": [0, 0, 0],
                                 "spacing_mm": 2}, tmp_path)
    assert isinstance(heightmap, Heightmap) and heightmap.heights_mm.shape == (3, 4)


@pytest.mark.parametrize(("table", "message"), [
    ({"shape": "cone"}, r"emulator.part.shape = 'cone': must be one of plane"),
    ({"shape": "sphere", "radius_mm": 5}, r"missing emulator.part.centre_mm"),
    ({"shape": "plane", "point_mm": [0, 0, 0], "normal": [0, 0, 1], "radius_mm": 3},
     r"unknown emulator.part.radius_mm"),
    ({"shape": "plane", "point_mm": [0, 0], "normal": [0, 0, 1]},
     r"emulator.part.point_mm = \[0, 0\]: must be 3 numbers"),
    ({"shape": "sphere", "centre_mm": [0, 0, 0], "radius_mm": 5, "concave": "yes"},
     r"emulator.part.concave = 'yes': true or false"),
    ({"shape": "sphere", "centre_mm": [0, 0, 0], "radius_mm": -5}, r"sphere radius_mm must be"),
    ({"shape": "heightmap", "file": "none.csv", "origin_mm": [0, 0, 0], "spacing_mm": 1},
     r"emulator.part.file: cannot read the height map"),
])
def test_bad_tables_are_refused_naming_the_key(table: dict[str, Any], message: str) -> None:
    """A ConfigError (a ValueError) whose message names the key."""
    with pytest.raises(ConfigError, match=message):
        part_from_table(table)
