"""Physical bounds at load: a file whose digest is right but whose values are absurd is refused.

What a hostile review found: ``cutoff_hz = 1e9`` and a tool of 10^6 kg loaded, because the
digest proves only that a file is the one written. Each case below rewrites one
value of a good file and recomputes the digest, as a hand-made file would.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from forcelearn.calibration import dumps, load_calibration
from forcelearn.calibration.file_format import content_digest, to_document
from forcelearn.errors import ConfigError
from forcelearn.tools.fuzz.targets import filled_calibration as good_calibration


def write_with(path: Path, section: str, key: str, value: Any, index: int | None = None) -> Path:
    """Write the good calibration with one value replaced and a correct digest."""
    doc = to_document(good_calibration())
    table = doc[section] if section != "pose" else doc["tool"]["pose"][0]
    if index is None:
        table[key] = value
    else:
        items = [list(v) if isinstance(v, tuple) else v for v in table[key]]
        items[index] = value
        table[key] = items
    doc["digest"] = content_digest(doc)
    path.write_text(dumps(doc))
    return path


def test_the_good_calibration_loads(tmp_path: Path) -> None:
    """The bounds refuse nothing a real calibration holds (so each refusal below is the value)."""
    assert load_calibration(write_with(tmp_path / "c.toml", "sensor", "cutoff_hz", 125.0)).sensor


@pytest.mark.parametrize(
    ("section", "key", "value", "index", "named"),
    [
        ("sensor", "cutoff_hz", 1e9, None, "sensor.cutoff_hz"),
        ("tool", "mass_kg", 1e6, None, "tool.mass_kg"),
        ("tool", "mass_kg", 50.0, None, "tool.mass_kg"),  # 490 N on a 400 N sensor
        ("tool", "mass_std_kg", 1e6, None, "tool.mass_std_kg"),
        ("tool", "com_mm", 1e5, 2, "tool.com_mm[2]"),
        ("tool", "force_bias_n", 1e5, 0, "tool.force_bias_n[0]"),
        ("tool", "torque_bias_nm", -500.0, 1, "tool.torque_bias_nm[1]"),
        ("tool", "condition_number", 1e30, None, "tool.condition_number"),
        ("noise", "bias", 401.0, 2, "noise.bias[2]"),  # beyond Fz's 400 N full scale
        ("noise", "drift_per_s", 1e6, 0, "noise.drift_per_s[0]"),
        ("noise", "duration_s", 1e12, None, "noise.duration_s"),
        ("noise", "rate_hz", 1e12, None, "noise.rate_hz"),
        ("pose", "mean", 1e7, 3, "tool.pose[0].mean[3]"),
        ("pose", "residual", -1e7, 0, "tool.pose[0].residual[0]"),
        ("matrix_check", "rms_residual_fit", 1e9, 1, "matrix_check.rms_residual_fit[1]"),
    ],
)
def test_an_absurd_value_is_refused_by_its_key_with_the_bound(
    tmp_path: Path, section: str, key: str, value: float, index: int | None, named: str
) -> None:
    """Each value beyond its physical bound: ConfigError naming the key and the bound."""
    path = write_with(tmp_path / "c.toml", section, key, value, index)
    with pytest.raises(ConfigError, match=re.escape(named)) as error:
        load_calibration(path)
    assert "out of bounds" in str(error.value) and "<=" in str(error.value)


def test_a_huge_calibration_matrix_entry_is_refused(tmp_path: Path) -> None:
    """C is near the identity; an entry of 1e9 is refused by its row."""
    doc = to_document(good_calibration())
    doc["matrix_check"]["matrix"] = [[1e9 if i == j == 4 else float(i == j) for j in range(6)]
                                     for i in range(6)]
    doc["digest"] = content_digest(doc)
    (tmp_path / "c.toml").write_text(dumps(doc))
    with pytest.raises(ConfigError, match=re.escape("matrix_check.matrix[4][4]")):
        load_calibration(tmp_path / "c.toml")


def test_a_tool_whose_gravity_moment_saturates_the_sensor_is_refused(tmp_path: Path) -> None:
    """30 kg at 200 mm is 59 N*m on a 20 N*m sensor (each value alone is within bounds)."""
    doc = to_document(good_calibration())
    doc["tool"]["mass_kg"] = 30.0
    doc["tool"]["com_mm"] = [0.0, 0.0, 200.0]
    doc["digest"] = content_digest(doc)
    (tmp_path / "c.toml").write_text(dumps(doc))
    with pytest.raises(ConfigError, match=r"tool\.com_mm .*gravity moment"):
        load_calibration(tmp_path / "c.toml")


@pytest.mark.parametrize("text", ["nan", "inf", "-1.0"])
def test_nan_infinite_and_negative_variances_stay_refused(tmp_path: Path, text: str) -> None:
    """A NaN, infinite or negative noise variance is refused naming noise.covariance."""
    path = write_with(tmp_path / "c.toml", "sensor", "cutoff_hz", 125.0)
    source = path.read_text()
    first_row = re.search(r"covariance = \[\s*\[\s*([^,\]]+)", source)
    assert first_row is not None
    path.write_text(source[: first_row.start(1)] + text + source[first_row.end(1):])
    with pytest.raises(ConfigError, match=r"noise\.covariance"):
        load_calibration(path)
