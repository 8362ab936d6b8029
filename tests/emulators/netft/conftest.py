"""Fixtures: an emulated Net F/T on loopback."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from netft_support import start

from forcelearn.emulators.netft import NetFtEmulator


@pytest.fixture()
def emulator() -> Iterator[NetFtEmulator]:
    """A default emulated box with the tool in the sponge."""
    with start() as emu:
        yield emu
