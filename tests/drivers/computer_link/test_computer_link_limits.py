"""Client-side limits refuse a command before any byte leaves the PC; config validation."""

from __future__ import annotations

import time

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import Limits, LinkConfig
from forcelearn.emulators.robot_controller.kinematics import HOME, TOOL_DOWN
from forcelearn.errors import ConfigError, SafetyStop

TIGHT = Limits(
    workspace_min_mm=(850.0, -50.0, 550.0),
    workspace_max_mm=(950.0, 50.0, 650.0),
    max_step_mm=5.0,
    max_speed_mm_s=100.0,
)


def settled_bytes_received(emulator, quiet_s: float = 0.05, limit_s: float = 2.0) -> int:
    """Wait until the emulator's byte count stops changing (the driver's trailing DLE ACK).

    The driver acknowledges each reply after it has read it, so the last ACK of
    the previous call may still be on its way when the test takes its baseline.
    """
    deadline = time.monotonic() + limit_s
    count = emulator.bytes_received
    quiet_since = time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.005)
        now = emulator.bytes_received
        if now != count:
            count, quiet_since = now, time.monotonic()
        elif time.monotonic() - quiet_since >= quiet_s:
            return count
    raise AssertionError("the emulator kept receiving bytes for 2 s")


@pytest.mark.parametrize(
    ("command", "match"),
    [
        (lambda r: r.move_to(Pose(900.0, 0.0, 540.0, TOOL_DOWN)), "workspace"),
        (lambda r: r.move_by(dx_mm=4.0, dy_mm=4.0), "step"),
        (lambda r: r.move_to(HOME.moved(dz_mm=-5.01)), "step"),
        (lambda r: r.move_to(HOME.moved(dx_mm=float("nan"))), "workspace"),
        (lambda r: r.set_speed(100.5), "speed"),
        (lambda r: r.set_speed(0.0), "speed"),
    ],
)
def test_command_outside_a_limit_is_refused_before_any_byte_is_sent(
    emulator, connect, command, match
) -> None:
    """SafetyStop names the limit; the controller receives nothing and does not move."""
    robot = connect(emulator.url, limits=TIGHT)
    received = settled_bytes_received(emulator)
    with pytest.raises(SafetyStop, match=match):
        command(robot)
    assert settled_bytes_received(emulator) == received
    assert emulator.move_count == 0


def test_step_limit_is_measured_from_the_last_commanded_position(emulator, connect) -> None:
    """Steps chain: two 4 mm moves pass, the reference follows each accepted target."""
    robot = connect(emulator.url, limits=TIGHT)
    robot.move_by(dz_mm=-4.0)
    robot.move_to(HOME.moved(dz_mm=-8.0))
    assert emulator.move_count == 2
    with pytest.raises(SafetyStop, match="step"):
        robot.move_to(HOME)


def test_non_unit_quaternion_is_a_value_error(emulator, connect) -> None:
    """A malformed orientation is a bad argument, refused before sending."""
    robot = connect(emulator.url)
    received = settled_bytes_received(emulator)
    with pytest.raises(ValueError, match="unit length"):
        robot.move_to(Pose(900.0, 0.0, 600.0, (1.0, 1.0, 0.0, 0.0)))
    assert settled_bytes_received(emulator) == received


def test_link_config_from_dict_builds_and_names_bad_keys() -> None:
    """A TOML table becomes a frozen config; unknown or bad keys are named in the error."""
    config = LinkConfig.from_dict(
        {"url": "/dev/ttyS0", "baudrate": 19200, "limits": {"workspace_min_mm": [0, 0, 0]}}
    )
    assert config.baudrate == 19200
    assert config.limits.workspace_min_mm == (0, 0, 0)
    with pytest.raises(ConfigError, match="baud_rate"):
        LinkConfig.from_dict({"url": "x", "baud_rate": 9600})
    with pytest.raises(ConfigError, match="max_stepmm"):
        LinkConfig.from_dict({"url": "x", "limits": {"max_stepmm": 1}})
    with pytest.raises(ConfigError, match="ack_timeout_s"):
        LinkConfig(url="x", ack_timeout_s=0)
    with pytest.raises(ConfigError, match="max_step_mm"):
        Limits(max_step_mm=-1)
    with pytest.raises(ConfigError, match=r"workspace_min_mm\[2\]"):
        Limits(workspace_min_mm=(0, 0, 10), workspace_max_mm=(1, 1, 10))
