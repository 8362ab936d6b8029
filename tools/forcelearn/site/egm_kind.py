"""``[robot] kind = "egm"``: an ABB controller guided by Externally Guided Motion over UDP.

Real: the driver binds ``[robot] host:port`` and answers the controller.
Emulated (``host = "emulated"``): the driver runs in lockstep (the one
simulated clock; docs/egm.md "Lockstep") with the EGM controller emulator,
which drives the cell's shared arm
(:class:`~forcelearn.emulators.egm.PhysicsMotion`), so the sponge and the
sensor see the arm EGM moves. In this process the controller is
:class:`~forcelearn.emulators.egm.InProcessEgmController` (the same bytes with
no UDP hand-over per 4 ms cycle), or with the route ``EgmRoute("udp")``
(``CellSession(config, routes={"egm": EgmRoute("udp")})``) the UDP
emulator's thread toward the driver's loopback port; for ``forcelearn
emulate`` it sends from 127.0.0.1 to the PC's ``--egm-port`` (this kind's
option), repeating its waiting cycle until a driver answers, so one client may
follow another.
"""

from __future__ import annotations

import argparse
import contextlib
import socket
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any, Literal, cast

from forcelearn.config import build
from forcelearn.devices import Robot
from forcelearn.drivers.egm import EgmConfig, EgmRobot, open_egm_robot
from forcelearn.drivers.limits import Limits
from forcelearn.emulators.egm import (
    EgmControllerConfig,
    EgmControllerEmulator,
    EgmEmulatorBase,
    InProcessEgmController,
    PhysicsMotion,
    egm_motion_params,
    start_emulated_egm,
)
from forcelearn.emulators.egm.servo import ServoParams
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.arm_motion import ArmMotion
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError, SafetyStop
from forcelearn.site.config import EMULATED
from forcelearn.site.kinds import (
    CellView,
    FarEnd,
    FarEndOptions,
    Polling,
    Printer,
    RobotConfig,
    RobotKind,
    typed_part,
)

EMULATED_EGM_WATCHDOG_S = 5.0
"""Watchdog of the emulated EGM link, s (wall time: the emulator is a thread of a loaded host)."""
EMULATED_EGM_FIRST_MESSAGE_S = 10.0
"""How long the emulated cell waits for the EGM emulator's first cycle, s (wall time)."""
EGM_ROUTES = ("in_process", "udp")
RAPID_RESTART_S = 1.0
"""The emulated controller runs rapid/ForcelearnEGM.modx: after a CommTimeout its ERROR handler
waits this long (WaitTime 1) and opens a new EGM session from where the robot holds, s."""


@dataclass(frozen=True)
class EgmRoute:
    """How the emulated EGM controller reaches the driver (this kind's route options).

    Attributes:
        route: in process (``run``): ``"in_process"`` (the driver takes the
            controller's socket-like end) or ``"udp"`` (loopback datagrams).
        port: ``forcelearn emulate``: the PC's UDP port the controller sends to
            (0: a free one).
    """

    route: Literal["in_process", "udp"] = "in_process"
    port: int = 0

    def __post_init__(self) -> None:
        if self.route not in EGM_ROUTES:
            raise ValueError(f"EGM route must be one of {EGM_ROUTES}, got {self.route!r}")


def egm_of(config: CellView) -> EgmConfig:
    """``[robot]`` of an EGM cell (``ConfigError`` for another kind)."""
    return typed_part(config.robot, EgmConfig, "[robot]", KIND.label)


def servo_of(config: CellView) -> ServoParams:
    """``[emulator.egm]``: the emulated controller's control lag and servo."""
    return typed_part(KIND.model(config.emulator), ServoParams, "[emulator.egm]", KIND.label)


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 free right now (for the PC side of EGM)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def egm_arm(config: CellView, physics: CellPhysics) -> ArmMotion:
    """Attach (once) and return the shared arm moved by EGM: the cell's arm with EGM's servo."""
    if physics.motion is None:
        arm = config.emulator.effective().arm
        params = egm_motion_params(arm.motion_params(), servo_of(config), arm.max_speed_mm_s)
        physics.attach_motion(ArmMotion(params, arm.home))
    assert physics.motion is not None
    return physics.motion


def controller_config(config: CellView) -> EgmControllerConfig:
    """The emulated controller: the config's RobotWare and cycle, the cell's arm and servo."""
    robot = config.robot if isinstance(config.robot, EgmConfig) else KIND.default_config()
    arm = config.emulator.effective().arm
    return EgmControllerConfig(
        version=robot.version,
        sample_period_s=robot.sample_period_s,
        servo=servo_of(config),
        workspace_min_mm=arm.workspace_min_mm,
        workspace_max_mm=arm.workspace_max_mm,
        max_speed_mm_s=arm.max_speed_mm_s,
        arm=arm,
        restart_after_s=RAPID_RESTART_S,
    )


class EgmFarEnd(FarEnd):
    """The EGM controller emulator, in process (``run``) or on loopback UDP (``emulate``).

    The UDP route of ``run`` starts its controller only once the driver has
    bound its port (:meth:`connect`).
    """

    def __init__(self, config: CellView, physics: CellPhysics, options: FarEndOptions) -> None:
        super().__init__()
        route = options.routes.get(KIND.name, EgmRoute())
        if not isinstance(route, EgmRoute):
            raise TypeError(f"the EGM kind's route options are an EgmRoute, not {route!r}")
        egm_arm(config, physics)
        self.physics = physics
        self.controller = controller_config(config)
        self.version = self.controller.version
        self.route = route.route if options.in_process else "served"
        self.pc_port = 0
        """The PC's UDP port the controller sends to (``emulate``)."""
        self.emulator: EgmEmulatorBase | None = None
        if self.route == "in_process":
            self._add(InProcessEgmController(
                physics=physics, clock=physics.clock, config=self.controller,
                motion=PhysicsMotion(physics),
            ))
        elif self.route == "served":
            self.pc_port = route.port or free_udp_port()
            self._add(EgmControllerEmulator(
                self.pc_port, physics=physics, clock=physics.clock, config=self.controller,
                motion=PhysicsMotion(physics), lockstep=True,
            ))

    def _add(self, emulator: EgmEmulatorBase) -> None:
        self.emulator = emulator
        self.emulators.append(emulator)

    def connect(self, driver_port: int) -> None:
        """UDP route of ``run``: start the controller toward the driver's bound port."""
        self._add(start_emulated_egm(
            self.physics, self.physics.clock, driver_port, self.controller,
            motion=PhysicsMotion(self.physics),
        ))

    def state_dict(self) -> dict[str, object]:
        """The controller's cycle state and, in a session, the driver's."""
        assert self.emulator is not None
        state: dict[str, object] = {"controller": self.emulator.state_dict()}
        if isinstance(self.driver, EgmRobot):
            state["driver"] = self.driver.state_dict()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (while the controller waits for the PC's answer)."""
        assert self.emulator is not None
        self.emulator.load_state_dict(state["controller"])
        if isinstance(self.driver, EgmRobot) and "driver" in state:
            self.driver.load_state_dict(state["driver"])

    def describe(self, paths: dict[str, str]) -> str:
        """Where the controller sends from and to."""
        assert isinstance(self.emulator, EgmControllerEmulator)
        return (f"robot EGM ({self.version}, UDP from 127.0.0.1:{self.emulator.port} to the PC "
                f"at 127.0.0.1:{self.pc_port}, lockstep)")

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        """The ``[robot]`` table of the PC side."""
        return [
            'kind = "egm"',
            'host = "127.0.0.1"',
            f"port = {self.pc_port}",
            f'version = "{self.version}"',
            "lockstep = true       # the emulator keeps step with the driver (one clock)",
            "watchdog_s = 5.0",
        ]

    def summary(self) -> str:
        """Cycles run and targets read."""
        assert self.emulator is not None
        return (f"{self.emulator.cycles} EGM cycles, {self.emulator.model.targets_read} "
                "planned poses read")


class EgmKind(RobotKind):
    """EGM (see the module doc)."""

    name = "egm"
    label = "EGM"
    config_type = EgmConfig
    emulator_table = "egm"
    model_type = ServoParams

    def load(self, table: dict[str, object], limits: Limits) -> EgmConfig:
        """``host`` defaults to the emulator; ``max_speed_mm_s`` joins [safety]'s limits."""
        table.setdefault("host", EMULATED)
        if "max_speed_mm_s" in table:  # EGM's ramp-speed ceiling is a robot key
            current = {f.name: getattr(limits, f.name) for f in fields(limits)}
            limits = build(Limits, {**current, "max_speed_mm_s": table.pop("max_speed_mm_s")},
                           "robot")
        return build(EgmConfig, {**table, "limits": limits}, "robot")

    def default_config(self) -> EgmConfig:
        """The emulated EGM config (what a cell of another robot kind would have)."""
        return self.load({}, Limits())

    def emulated(self, robot: RobotConfig) -> bool:
        """``host = "emulated"``."""
        return isinstance(robot, EgmConfig) and robot.host == EMULATED

    def describe(self, config: CellView) -> str:
        """The address the driver listens on, or the emulator."""
        if config.robot_emulated:
            return "built-in EGM controller emulator on loopback UDP (lockstep)"
        robot = egm_of(config)
        return (f"EGM {robot.version}: listening on UDP {robot.host}:{robot.port} for the "
                "controller (start the ForcelearnEGM RAPID program)")

    def location(self, config: CellView) -> str:
        """The port the driver listens on."""
        return f"{self.label} {egm_of(config).port}"

    def far_end(
        self, config: CellView, physics: CellPhysics, options: FarEndOptions
    ) -> EgmFarEnd:
        """The EGM controller emulator on the cell's shared arm."""
        return EgmFarEnd(config, physics, options)

    def add_emulate_arguments(self, parser: argparse.ArgumentParser) -> None:
        """``--egm-port``: the PC's UDP port the emulated controller sends to."""
        parser.add_argument(
            "--egm-port", type=int, default=0,
            help="the PC's UDP port the EGM controller sends to (default: a free one)",
        )

    def route_from_arguments(self, arguments: argparse.Namespace) -> EgmRoute:
        """The ``--egm-port`` given."""
        return EgmRoute(port=int(getattr(arguments, "egm_port", 0) or 0))

    def open(
        self, config: CellView, far_end: FarEnd | None, stack: contextlib.ExitStack
    ) -> EgmRobot:
        """The driver: on the real controller, or in lockstep with the emulator."""
        robot = egm_of(config)
        if far_end is None:
            driver = open_egm_robot(robot)
            stack.callback(driver.close)
            return driver
        assert isinstance(far_end, EgmFarEnd)
        driver_config = replace(
            robot,
            host="127.0.0.1",
            port=0,
            controller_host=None,  # the emulator sends from loopback, whatever the site's
            controller_port=None,
            lockstep=True,
            watchdog_s=max(robot.watchdog_s, EMULATED_EGM_WATCHDOG_S),
            first_message_timeout_s=EMULATED_EGM_FIRST_MESSAGE_S,
        )
        if isinstance(far_end.emulator, InProcessEgmController):
            driver = EgmRobot(driver_config, sock=far_end.emulator.socket())
        else:
            driver = EgmRobot(driver_config)
        stack.callback(driver.close)  # closed before its controller: its last answer goes out
        far_end.driver = driver
        if far_end.emulator is None:
            far_end.connect(driver.port)
        driver.wait_for_session()
        return driver

    def check(self, robot: Robot, say: Printer) -> Callable[[], None]:
        """The session as it holds; afterwards, fail if the target ever moved."""
        robot = cast(EgmRobot, robot)  # the driver this kind opened
        config = robot.config
        pose = robot.read_pose()
        status = robot.read_status()
        say(f"  robot   EGM session ({config.version}) on UDP {config.host}:{robot.port}: "
            f"motors {status.motor.name}, EGM {status.mci.name}, RAPID {status.rapid.name}, "
            f"controller time {status.controller_time_s:.3f} s")
        say(f"  robot   pose x {pose.x_mm:.2f}  y {pose.y_mm:.2f}  z {pose.z_mm:.2f} mm, "
            f"quaternion (w x y z) {' '.join(f'{q:.4f}' for q in pose.quaternion)}")
        stats = status.stats
        say(f"  robot   {stats.received} EgmRobot received, {stats.replies} answers (holds), "
            f"missed {stats.missed}, duplicates {stats.duplicates}, out of order "
            f"{stats.out_of_order}, unreadable {stats.bad_datagrams}")
        say(f"  robot   paired with the controller at {robot.controller_address}; ignored: "
            f"{stats.foreign_datagrams} from other hosts, {stats.wrong_version} of the other "
            f"RobotWare, {stats.seqno_jumps} seqno jumps, {stats.replays} replayed starts, "
            f"{stats.refused_sessions} refused session starts")
        robot.read_target()  # raises GuidanceStopped if the controller is not guided
        before = robot.target

        def unmoved() -> None:
            after = robot.target
            if after != before:
                raise SafetyStop(
                    f"the EGM target changed from {before} to {after} during the check: "
                    "something in this process commanded the robot"
                )
            status = robot.read_status()
            say(f"  robot   still guided: EGM {status.mci.name}, RAPID {status.rapid.name}; "
                "no target was sent other than the pose it reported")

        return unmoved

    def calibration_name(self, robot: Robot) -> str:
        """"ABB EGM" and the RobotWare of the session."""
        robot = cast(EgmRobot, robot)
        return f"ABB EGM {robot.config.version}"

    def polling(self, robot: RobotConfig, arm: ArmConfig) -> Polling:
        """Every feedback message: the sample period, each message stamped when it is sent."""
        if not isinstance(robot, EgmConfig):
            raise ConfigError(f"a {type(robot).__name__} is not an EGM config")
        period = float(robot.sample_period_s)
        return Polling(period, period)


KIND = EgmKind()
