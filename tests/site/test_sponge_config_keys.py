"""The sponge's model-family keys in ``[emulator.sponge]``: accepted, and refused by name."""

from __future__ import annotations

from pathlib import Path

import pytest

from forcelearn.errors import ConfigError
from forcelearn.site.config import load_cell_config


def _cell(tmp_path: Path, sponge: str) -> Path:
    path = tmp_path / "cell.toml"
    path.write_text(f"[emulator.sponge]\n{sponge}\n")
    return path


def test_model_family_keys_reach_the_sponge(tmp_path: Path) -> None:
    """Every new key of the TOML table arrives in the cell's SpongeParams."""
    config = load_cell_config(_cell(tmp_path, (
        "stiffening_exponent = 1.3\nstiffening_reference_mm = 8.0\nhysteresis_loss = 0.15\n"
        "hysteresis_depth_mm = 0.4\nhysteresis_travel_mm = 7.0\nfriction_coefficient = 0.2"
    )))
    sponge = config.emulator.sponge
    assert (sponge.stiffening_exponent, sponge.stiffening_reference_mm) == (1.3, 8.0)
    assert (sponge.hysteresis_loss, sponge.hysteresis_depth_mm) == (0.15, 0.4)
    assert sponge.hysteresis_travel_mm == 7.0
    assert sponge.friction_coefficient == 0.2


@pytest.mark.parametrize(
    ("line", "named"),
    [("friction_coefficient = -1.0", "friction_coefficient"),
     ("hysteresis_loss = 0.95", "hysteresis_loss"),
     ("stiffening_exponent = \"steep\"", "emulator.sponge.stiffening_exponent"),
     ("stiffening = 1.2", "emulator.sponge.stiffening")],
)
def test_bad_model_family_keys_are_config_errors_naming_the_key(
    tmp_path: Path, line: str, named: str
) -> None:
    """Out of range, not a number, or misspelt: a ConfigError that names the key."""
    with pytest.raises(ConfigError, match=named):
        load_cell_config(_cell(tmp_path, line))
