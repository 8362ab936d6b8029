"""Opening the Ethernet devices of a cell: ABB EGM (UDP) and ATI Net F/T, real or emulated.

Used by :class:`~forcelearn.site.session.CellSession` when ``[robot] kind
= "egm"`` or ``[sensor] kind = "netft"``. Each ``open_*`` returns an
:class:`Opened` pair: the driver (what the cell uses) and, on an emulated
cell, the emulator behind it; ``close()`` closes the driver first, then the
emulator (an EGM driver's last answer must still reach its controller).

Emulated EGM: the driver runs in lockstep (the one simulated clock; docs/egm.md
"Lockstep") with the in-process controller in its own thread
(:class:`~forcelearn.emulators.egm.InProcessEgmController`, the same bytes
with no UDP hand-over per 4 ms cycle), or, with ``route="udp"``, binds
127.0.0.1 on a free port and talks to the UDP emulator's thread. Either
controller drives the cell's shared arm
(:class:`~forcelearn.emulators.egm.PhysicsMotion`), so the sponge and the
sensor see the arm EGM moves. Emulated Net F/T: the box
emulator serves RDT, READCALINFO and HTTP on free loopback ports and samples
the shared physics on the cell's clock.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

from forcelearn.drivers.egm import EgmConfig, EgmRobotDriver, open_egm_robot
from forcelearn.drivers.netft import NetFtConfig, NetFtSensor
from forcelearn.emulators.egm import (
    EgmControllerConfig,
    EgmEmulatorBase,
    InProcessEgmController,
    PhysicsMotion,
    egm_motion_params,
    start_emulated_egm,
)
from forcelearn.emulators.netft.server import (
    MAX_RDT_RATE_HZ,
    NetFtEmulator,
    start_emulated_netft,
)
from forcelearn.emulators.physics.arm_motion import ArmMotion
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError, ForcelearnError
from forcelearn.site.config import CellConfig

log = logging.getLogger(__name__)

EMULATED_EGM_WATCHDOG_S = 5.0
"""Watchdog of the emulated EGM link, s (wall time: the emulator is a thread of a loaded host)."""
EMULATED_EGM_FIRST_MESSAGE_S = 10.0
"""How long the emulated cell waits for the EGM emulator's first cycle, s (wall time)."""

D = TypeVar("D")
E = TypeVar("E")


@dataclass
class Opened(Generic[D, E]):
    """A driver and, on an emulated cell, the emulator it talks to."""

    driver: D
    emulator: E | None = None

    def close(self) -> None:
        """Close the driver, then stop the emulator; safe to call twice."""
        try:
            self.driver.close()  # type: ignore[attr-defined]
        finally:
            if self.emulator is not None:
                stop = getattr(self.emulator, "stop", None) or self.emulator.close  # type: ignore[attr-defined]
                stop()


def egm_arm(config: CellConfig, physics: CellPhysics) -> ArmMotion:
    """Attach (once) and return the shared arm moved by EGM: the cell's arm with EGM's servo."""
    if physics.motion is None:
        arm = config.emulator.effective().arm
        params = egm_motion_params(arm.motion_params(), config.emulator.egm, arm.max_speed_mm_s)
        physics.attach_motion(ArmMotion(params, arm.home))
    assert physics.motion is not None
    return physics.motion


EGM_ROUTES = ("in_process", "udp")


def open_egm(
    config: CellConfig, physics: CellPhysics | None, route: str = "in_process"
) -> Opened[EgmRobotDriver, EgmEmulatorBase]:
    """Open the ``[robot] kind = "egm"`` robot: a real controller, or its emulator.

    ``route`` (emulated cell only): ``"in_process"`` or ``"udp"`` (loopback);
    the same bytes, cycles and results, the first without a thread hand-over.
    """
    robot = config.robot
    assert isinstance(robot, EgmConfig)
    if route not in EGM_ROUTES:
        raise ValueError(f"route must be one of {EGM_ROUTES}, got {route!r}")
    if not config.robot_emulated:
        return Opened(open_egm_robot(robot))
    assert physics is not None
    egm_arm(config, physics)
    arm = config.emulator.effective().arm
    controller = EgmControllerConfig(
        version=robot.version,
        sample_period_s=robot.sample_period_s,
        servo=config.emulator.egm,
        workspace_min_mm=arm.workspace_min_mm,
        workspace_max_mm=arm.workspace_max_mm,
        max_speed_mm_s=arm.max_speed_mm_s,
        arm=arm,
    )
    driver_config = replace(
        robot,
        host="127.0.0.1",
        port=0,
        controller_host=None,  # the emulator sends from loopback, whatever the site's address
        controller_port=None,
        lockstep=True,
        watchdog_s=max(robot.watchdog_s, EMULATED_EGM_WATCHDOG_S),
        first_message_timeout_s=EMULATED_EGM_FIRST_MESSAGE_S,
    )
    if route == "in_process":
        emulator = InProcessEgmController(
            physics=physics, clock=physics.clock, config=controller,
            motion=PhysicsMotion(physics),
        )
        opened: Opened[EgmRobotDriver, EgmEmulatorBase] = Opened(
            EgmRobotDriver(driver_config, sock=emulator.socket()), emulator
        )
    else:
        opened = Opened(EgmRobotDriver(driver_config))
    try:
        if route == "udp":
            opened.emulator = start_emulated_egm(
                physics, physics.clock, opened.driver.port, controller,
                motion=PhysicsMotion(physics),
            )
        opened.driver.wait_for_session()
    except BaseException:
        opened.close()
        raise
    return opened


def open_netft(
    config: CellConfig, physics: CellPhysics | None, seed: int
) -> Opened[NetFtSensor, NetFtEmulator]:
    """Open the ``[sensor] kind = "netft"`` sensor (initialised): the box, or its emulator."""
    sensor = config.sensor
    assert isinstance(sensor, NetFtConfig)
    emulator: NetFtEmulator | None = None
    if config.sensor_emulated:
        assert physics is not None
        options: dict[str, Any] = {"rdt_port": 0, "tcp_port": 0, "model": config.emulator.netft}
        if sensor.rdt_rate_hz is not None:
            if sensor.rdt_rate_hz > MAX_RDT_RATE_HZ:
                raise ConfigError(
                    f"[sensor] sensor.rdt_rate_hz = {sensor.rdt_rate_hz:g}: the emulated box "
                    f"streams at most {MAX_RDT_RATE_HZ:g} records/s"
                )
            options["rdt_rate_hz"] = sensor.rdt_rate_hz
        emulator = start_emulated_netft(physics, physics.clock, seed, **options)
        ports = emulator.ports
        sensor = replace(
            sensor,
            host=emulator.host,
            rdt_port=ports["rdt_port"],
            tcp_port=ports["tcp_port"],
            http_port=ports["http_port"],
        )
    try:
        driver = NetFtSensor(sensor)
    except BaseException:
        if emulator is not None:
            emulator.close()
        raise
    opened: Opened[NetFtSensor, NetFtEmulator] = Opened(driver, emulator)
    try:
        driver.initialise()
    except ForcelearnError as exc:  # keeps its type and fields (SensorFault...)
        opened.close()
        exc.add_note(
            f"check [sensor] host ({config.netft.host}), that the box is powered and "
            "on this subnet, and its calibration (docs/netft.md, On site)"
        )
        raise
    except BaseException:
        opened.close()
        raise
    return opened


def close_quietly(opened: Opened[Any, Any] | None) -> None:
    """Close ``opened`` if there is one (for exit stacks)."""
    if opened is not None:
        with contextlib.suppress(ForcelearnError):
            opened.close()
