"""Fixtures: an EGM driver and an emulated controller wired together on loopback UDP."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from typing import Any

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.egm import EgmConfig, EgmRobotDriver
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import EgmControllerConfig, EgmControllerEmulator
from forcelearn.emulators.physics.cell import CellPhysics

DOWN = (0.0, 1.0, 0.0, 0.0)
HOME = Pose(900.0, 0.0, 600.0, DOWN)

Pair = tuple[EgmRobotDriver, EgmControllerEmulator]


@pytest.fixture
def egm_pair() -> Iterator[Callable[..., Pair]]:
    """Make (driver, emulator) pairs; the driver waits for the session unless ``wait=False``.

    Keyword arguments: ``driver`` (EgmConfig fields), ``controller`` (EgmControllerConfig
    fields), ``emulator`` (EgmControllerEmulator arguments). Lockstep by default.
    """
    with ExitStack() as stack:

        def make(
            driver: dict[str, Any] | None = None,
            controller: dict[str, Any] | None = None,
            emulator: dict[str, Any] | None = None,
            wait: bool = True,
        ) -> Pair:
            driver_cfg = {"port": 0, "lockstep": True, "watchdog_s": 5.0} | (driver or {})
            robot = EgmRobotDriver(EgmConfig.from_dict(driver_cfg))
            stack.callback(robot.close)
            emulator_kw = {
                "physics": CellPhysics(pose=HOME),
                "clock": SimClock(),
                "config": EgmControllerConfig(**(controller or {})),
            } | (emulator or {})
            emu = EgmControllerEmulator(robot.port, **emulator_kw)
            stack.callback(emu.close)
            emu.start()
            if wait:
                robot.wait_for_session(5.0)
            return robot, emu

        yield make
