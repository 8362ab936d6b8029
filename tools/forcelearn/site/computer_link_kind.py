"""``[robot] kind = "computer_link"``: an ABB S4 controller over its serial computer link.

Real: pyserial opens ``[robot] url`` (a port name or a pyserial URL).
Emulated (``url = "emulated"``, the default): the robot-controller emulator,
in this process as ``forcelearn-robot://NAME`` (the same bytes as a pty,
answered in the driver's thread) or, for ``forcelearn emulate``, on a
pseudo-terminal another process opens. ``LinkRoute("pty")`` puts ``run``'s
emulator on a pty too (its own thread), as a real serial port is reached.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal, cast

from forcelearn.config import build
from forcelearn.devices import Robot
from forcelearn.drivers.computer_link import ComputerLinkRobot
from forcelearn.drivers.computer_link.config import LinkConfig
from forcelearn.drivers.limits import Limits
from forcelearn.emulators.clock import serial_char_time_s
from forcelearn.emulators.computer_link.server import ComputerLinkEmulator
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError, LinkError, SafetyStop
from forcelearn.protocols.computer_link import framing, messages
from forcelearn.site.config import EMULATED, EMULATED_LINK_TIMEOUT_S
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

LINK_ROUTES = ("in_process", "pty")


@dataclass(frozen=True)
class LinkRoute:
    """How ``run``'s emulated controller takes the driver's bytes (this kind's route option).

    ``"in_process"``: ``forcelearn-robot://NAME``, a pyserial port whose writes the
    emulator answers in the writer's thread; ``"pty"``: a pseudo-terminal served by
    the emulator's thread, as a real port is. The same bytes and simulated times
    either way (tests/envs/test_surface_routes.py).
    """

    route: Literal["in_process", "pty"] = "in_process"

    def __post_init__(self) -> None:
        if self.route not in LINK_ROUTES:
            raise ValueError(f"computer-link route must be one of {LINK_ROUTES}, "
                             f"got {self.route!r}")


ROBOT_LINK = "robot"
"""Name of the stable symlink to the robot's pty (``forcelearn emulate --link-dir``)."""
EMULATE_HINT = (" (for `forcelearn emulate`, name the stable links it prints, which survive "
                "restarts, rather than the /dev/pts paths)")


def link_of(config: CellView) -> LinkConfig:
    """``[robot]`` of a computer-link cell (``ConfigError`` for another kind)."""
    return typed_part(config.robot, LinkConfig, "[robot]", KIND.label)


def link_char_time_s(config: CellView) -> float:
    """Seconds per character of the emulated robot link (0 in the ideal profile)."""
    if config.emulator.ideal:
        return 0.0
    robot = config.robot if isinstance(config.robot, LinkConfig) else KIND.default_config()
    return serial_char_time_s(robot.baudrate, robot.bytesize, robot.parity, robot.stopbits)


class ComputerLinkFarEnd(FarEnd):
    """The robot-controller emulator on a pty (``emulate``) or in process (``run``)."""

    def __init__(self, config: CellView, physics: CellPhysics, options: FarEndOptions) -> None:
        super().__init__()
        route = options.routes.get(KIND.name, LinkRoute())
        if not isinstance(route, LinkRoute):
            raise TypeError(f"the computer link's route options are a LinkRoute, not {route!r}")
        in_process = options.in_process and route.route == "in_process"
        self.emulator: ComputerLinkEmulator = ComputerLinkEmulator(
            "inproc" if in_process else "pty",
            config=config.emulator.effective().arm,
            physics=physics,
            char_time_s=link_char_time_s(config),
        )
        self.emulators = [self.emulator]

    def state_dict(self) -> dict[str, object]:
        """The controller's motion and the link's wire timelines."""
        state: dict[str, object] = self.emulator.engine.state_dict()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.emulator.engine.load_state_dict(state)

    def links(self) -> dict[str, str]:
        """The pty, linked as ``robot``."""
        return {ROBOT_LINK: self.emulator.address}

    def describe(self, paths: dict[str, str]) -> str:
        """Where another process reaches the controller."""
        return f"robot link (computer link, pty): {paths[ROBOT_LINK]}"

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        """The ``[robot]`` table reaching the pty."""
        return [f'url = "{paths[ROBOT_LINK]}"']

    def summary(self) -> str:
        """Moves the controller executed."""
        return f"{self.emulator.move_count} robot moves executed"


class ComputerLinkKind(RobotKind):
    """The computer link (see the module doc)."""

    name = "computer_link"
    label = "computer link"
    config_type = LinkConfig
    emulated_key = "url"

    def load(self, table: dict[str, object], limits: Limits) -> LinkConfig:
        """``url`` defaults to the emulator, whose timeouts default to EMULATED_LINK_TIMEOUT_S."""
        table = {"url": EMULATED, **table}
        if table["url"] == EMULATED:
            for key in ("ack_timeout_s", "reply_timeout_s"):
                table.setdefault(key, EMULATED_LINK_TIMEOUT_S)
        return replace(build(LinkConfig, table, "robot"), limits=limits)

    def default_config(self) -> LinkConfig:
        """The emulated link's config (what a cell of another robot kind would have)."""
        return self.load({}, Limits())

    def emulated(self, robot: RobotConfig) -> bool:
        """``url = "emulated"``."""
        return isinstance(robot, LinkConfig) and robot.url == EMULATED

    def describe(self, config: CellView) -> str:
        """Port and framing, or the emulator."""
        if config.robot_emulated:
            return "built-in robot-controller emulator on a pty"
        robot = link_of(config)
        return (f"port {robot.url} at {robot.baudrate} baud, {robot.bytesize}"
                f"{robot.parity}{robot.stopbits:g}")

    def location(self, config: CellView) -> str:
        """The port."""
        return f"{self.label} {link_of(config).url}"

    def missing(self, config: CellView) -> list[str]:
        """The serial port, if it is a path that does not exist."""
        url = link_of(config).url
        if config.robot_emulated or "://" in url or Path(url).exists():
            return []
        return [f"robot link: port {url} does not exist; check [robot] url and the cable"
                + EMULATE_HINT]

    def far_end(
        self, config: CellView, physics: CellPhysics, options: FarEndOptions
    ) -> ComputerLinkFarEnd:
        """The robot-controller emulator (``start()`` serves it)."""
        return ComputerLinkFarEnd(config, physics, options)

    def open(
        self, config: CellView, far_end: FarEnd | None, stack: contextlib.ExitStack
    ) -> ComputerLinkRobot:
        """The driver on the configured port, or on the in-process emulator's URL."""
        robot_config = link_of(config)
        if far_end is not None:
            assert isinstance(far_end, ComputerLinkFarEnd)
            robot_config = replace(robot_config, url=far_end.emulator.start())
        try:
            robot = ComputerLinkRobot(robot_config)
        except LinkError as exc:  # keeps its type (LinkTimeout, ProtocolError...)
            exc.add_note(
                "check [robot] url (port name), baudrate and framing, that the "
                "controller is on and its computer link enabled"
            )
            raise
        stack.callback(robot.close)
        if far_end is not None:
            far_end.driver = robot
        return robot

    def check(self, robot: Robot, say: Printer) -> Callable[[], None]:
        """Identify, pose, status; afterwards, fail if the move counter changed."""
        robot = cast(ComputerLinkRobot, robot)  # the driver this kind opened
        major, minor = messages.PROTOCOL_VERSION
        say(f"  robot   controller {robot.controller_model!r}, computer link {major}.x "
            f"(this driver speaks {major}.{minor})")
        pose = robot.read_pose()
        say(f"  robot   pose x {pose.x_mm:.2f}  y {pose.y_mm:.2f}  z {pose.z_mm:.2f} mm, "
            f"quaternion (w x y z) {' '.join(f'{q:.4f}' for q in pose.quaternion)}")
        before = robot.read_status()
        say(f"  robot   {'MOVING' if before.moving else 'still'}, last error "
            f"{before.last_error}, {before.move_count} moves since power-up")

        def unmoved() -> None:
            after = robot.read_status()
            if after.move_count != before.move_count:
                raise SafetyStop(
                    f"the controller's move counter went from {before.move_count} to "
                    f"{after.move_count} during the check: something else commands this "
                    "robot; stop and find it before running"
                )

        return unmoved

    def calibration_name(self, robot: Robot) -> str:
        """The model the controller identifies as."""
        robot = cast(ComputerLinkRobot, robot)
        return robot.controller_model

    def polling(self, robot: RobotConfig, arm: ArmConfig) -> Polling:
        """One READ_STATUS exchange at the line's character time.

        The request, the reply after the controller's ``reply_latency_s`` (its
        DLE ACK within it), the PC's DLE ACK; the controller stamps the poll when
        the request has arrived.
        """
        if not isinstance(robot, LinkConfig):
            raise ConfigError(f"a {type(robot).__name__} is not a computer link's config")
        bits = 1 + robot.bytesize + (0 if robot.parity == "N" else 1) + robot.stopbits
        char_s = bits / robot.baudrate
        request = framing.encode(messages.encode_request(messages.Command.READ_STATUS, 1))
        reply = framing.encode(messages.encode_reply(messages.Reply(
            messages.Command.READ_STATUS, 1, messages.ErrorCode.OK,
            body=messages.status_body(messages.Status(False, True, 0, 0, 0.0)))))
        ack = len(framing.Control.ACK.wire)
        unanswered = (len(request) + ack) * char_s
        return Polling(unanswered + arm.reply_latency_s + len(reply) * char_s, unanswered)


KIND = ComputerLinkKind()
