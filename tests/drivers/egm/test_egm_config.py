"""EGM driver configuration: errors name the key; the example cell's [robot] table loads."""

from __future__ import annotations

import pytest

from forcelearn.config import build
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.errors import ConfigError


def test_config_errors_name_the_key() -> None:
    """Config errors name the key (the cell config's parser, forcelearn.config.build)."""
    assert build(EgmConfig, {"port": 0, "version": "rw6"}, "robot").version == "rw6"
    for table, key in [
        ({"prot": 1}, "prot"),
        ({"port": 70000}, "robot.port"),
        ({"version": "rw5"}, "robot.version"),
        ({"sample_period_s": 0.005}, "robot.sample_period_s"),
        ({"watchdog_s": 0}, "robot.watchdog_s"),
        ({"max_step_mm": 1}, "robot.max_step_mm"),  # a limit: [safety]'s (cell config)
        ({"speed_mm_s": 500.0}, "robot.limits.max_speed_mm_s"),
    ]:
        with pytest.raises(ConfigError, match=key):
            build(EgmConfig, table, "robot")


def test_the_example_egm_cell_config_loads() -> None:
    """examples/egm-cell.toml's [robot] table is a valid EgmConfig (through the cell config)."""
    from pathlib import Path

    from forcelearn.site.config import load_cell_config

    path = Path(__file__).parents[3] / "examples" / "egm-cell.toml"
    config = load_cell_config(path).robot
    assert isinstance(config, EgmConfig)
    assert (config.version, config.port, config.lockstep) == ("rw6", 6510, False)
    assert config.limits.max_step_mm == 10.0 and config.limits.max_speed_mm_s == 250.0
