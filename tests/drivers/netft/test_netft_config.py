"""NetFtConfig: bad values are refused naming the key; the example's [sensor] table loads."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from forcelearn.config import build
from forcelearn.drivers.netft.config import NetFtConfig
from forcelearn.errors import ConfigError

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "netft-cell.toml"


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("rdt_port", 70000),
        ("calibration_source", "ftp"),
        ("counts_per_force", 0),
        ("counts_per_torque", float("nan")),
        ("force_unit", "stone"),
        ("mode", "async"),
        ("burst_records", 0),
        ("stale_timeout_s", 0.0),
        ("near_saturation_fraction", 1.5),
        ("full_scales", (1.0, 2.0)),
        ("rdt_rate_hz", -7000.0),
    ],
)
def test_bad_values_name_their_key(key: str, value: object) -> None:
    """Each bad value raises ConfigError whose message names sensor.<key>."""
    with pytest.raises(ConfigError, match=f"sensor.{key}"):
        NetFtConfig(**{key: value})


def test_example_sensor_table_builds_the_config() -> None:
    """examples/netft-cell.toml's [sensor] table (minus ``kind``) is a valid NetFtConfig."""
    table = tomllib.loads(EXAMPLE.read_text())["sensor"]
    assert table.pop("kind") == "netft"
    config = build(NetFtConfig, table, "sensor")
    # as shipped the example runs on the emulated cell; on site host is the box's address
    assert config.host == "emulated" and config.calibration_source == "http"
    with pytest.raises(ConfigError, match=r"sensor\.hots"):
        build(NetFtConfig, {**table, "hots": "x"}, "sensor")
