"""Fixtures: an EGM driver and an emulated controller, over loopback UDP or in process."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from typing import Any

import pytest

from forcelearn.config import build
from forcelearn.devices import Pose
from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.drivers.limits import Limits
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import (
    EgmControllerConfig,
    EgmControllerEmulator,
    EgmEmulatorBase,
    InProcessEgmController,
)
from forcelearn.emulators.physics.cell import CellPhysics

DOWN = (0.0, 1.0, 0.0, 0.0)
HOME = Pose(900.0, 0.0, 600.0, DOWN)

Pair = tuple[EgmRobot, EgmEmulatorBase]
ROUTES = ("udp", "in_process")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Every test of an ``egm_pair`` runs on both routes, unless marked ``udp_only``.

    ``udp_only``: the test is about the UDP emulator thread's wall-time
    behaviour (patience, real mode), which the in-process route does not have.
    """
    if "egm_route" in metafunc.fixturenames:
        udp_only = metafunc.definition.get_closest_marker("udp_only") is not None
        metafunc.parametrize("egm_route", ROUTES[:1] if udp_only else ROUTES)


@pytest.fixture
def egm_pair(egm_route: str) -> Iterator[Callable[..., Pair]]:
    """Make (driver, emulator) pairs; the driver waits for the session unless ``wait=False``.

    Keyword arguments: ``driver`` (EgmConfig fields), ``controller`` (EgmControllerConfig
    fields), ``emulator`` (emulator arguments). Lockstep by default.
    """
    with ExitStack() as stack:

        def make(
            driver: dict[str, Any] | None = None,
            controller: dict[str, Any] | None = None,
            emulator: dict[str, Any] | None = None,
            wait: bool = True,
        ) -> Pair:
            driver_cfg = {"port": 0, "lockstep": True, "watchdog_s": 5.0} | (driver or {})
            if "limits" in driver_cfg:
                driver_cfg["limits"] = Limits(**driver_cfg["limits"])
            config = build(EgmConfig, driver_cfg, "robot")
            emulator_kw = {
                "physics": CellPhysics(pose=HOME),
                "clock": SimClock(),
                "config": EgmControllerConfig(**(controller or {})),
            } | (emulator or {})
            emu: EgmEmulatorBase
            if egm_route == "in_process":
                emu = InProcessEgmController(**emulator_kw)
                stack.callback(emu.close)
                robot = EgmRobot(config, sock=emu.socket())
                stack.callback(robot.close)
            else:
                robot = EgmRobot(config)
                stack.callback(robot.close)
                emu = EgmControllerEmulator(robot.port, **emulator_kw)
                stack.callback(emu.close)
                emu.start()
            if wait:
                robot.wait_for_session(5.0)
            return robot, emu

        yield make
