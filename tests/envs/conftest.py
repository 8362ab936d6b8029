"""Shared fixtures of the env tests."""

from __future__ import annotations

import dataclasses

import pytest

from forcelearn.site import CellConfig, load_cell_config


@pytest.fixture
def no_probe_config() -> CellConfig:
    """The emulated default cell without the surface probe (a reset is then one press in).

    For tests of the env's mechanics, not of the probe's map: the output map is then
    the fallback (start Y, 2 mm, 15 mm; docs/surface.md).
    """
    config = load_cell_config(None)
    return dataclasses.replace(config, probe=dataclasses.replace(config.probe, enabled=False))
