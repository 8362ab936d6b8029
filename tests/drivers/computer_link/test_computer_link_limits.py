"""Client-side limits refuse a command before any byte leaves the PC; config validation."""

from __future__ import annotations

import math

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import Limits, LinkConfig
from forcelearn.emulators.physics.arm import HOME, TOOL_DOWN
from forcelearn.errors import ConfigError, InvalidTarget, SafetyStop

TIGHT = Limits(
    workspace_min_mm=(850.0, -50.0, 550.0),
    workspace_max_mm=(950.0, 50.0, 650.0),
    max_step_mm=5.0,
    max_speed_mm_s=100.0,
)


def count_writes(robot, monkeypatch: pytest.MonkeyPatch) -> list[bytes]:
    """Record every write the driver makes to its port from now on (no waiting for silence)."""
    writes: list[bytes] = []
    port = robot._port
    original = port.write

    def write(data: bytes) -> int | None:
        writes.append(bytes(data))
        return original(data)

    monkeypatch.setattr(port, "write", write)
    return writes


@pytest.mark.parametrize(
    ("command", "match"),
    [
        (lambda r: r.move_to(Pose(900.0, 0.0, 540.0, TOOL_DOWN)), "workspace"),
        (lambda r: r.move_by(dx_mm=4.0, dy_mm=4.0), "step"),
        (lambda r: r.move_to(HOME.moved(dz_mm=-5.01)), "step"),
        (lambda r: r.move_to(HOME.moved(dx_mm=float("nan"))), "workspace"),
        (lambda r: r.set_speed(100.5), "speed"),
        (lambda r: r.set_speed(0.0), "speed"),
        (lambda r: r.move_to(HOME.moved(dx_mm=1e39)), "workspace"),  # > float32, finite
        (lambda r: r.move_by(dx_mm=1e39), "workspace"),
        (lambda r: r.move_to(Pose(900.0, 0.0, 600.0, (1.0, 0.0, 0.0))), "4 finite"),
        (lambda r: r.move_to(Pose(900.0, 0.0, 600.0, (1.0, 0.0, 0.0, math.inf))), "4 finite"),
        (lambda r: r.move_to(Pose(900.0, 0.0, 600.0, ("w", 0, 0, 0))), "4 numbers"),
    ],
)
def test_command_outside_a_limit_is_refused_before_any_byte_is_sent(
    emulator, connect, monkeypatch, command, match
) -> None:
    """SafetyStop names the limit; the driver writes nothing and the robot does not move."""
    robot = connect(emulator.address, limits=TIGHT)
    writes = count_writes(robot, monkeypatch)
    with pytest.raises(SafetyStop, match=match):
        command(robot)
    assert writes == []
    assert emulator.move_count == 0


def test_step_limit_is_measured_from_the_last_commanded_position(emulator, connect) -> None:
    """Steps chain: two 4 mm moves pass, the reference follows each accepted target."""
    robot = connect(emulator.address, limits=TIGHT)
    robot.move_by(dz_mm=-4.0)
    robot.move_to(HOME.moved(dz_mm=-8.0))
    assert emulator.move_count == 2
    with pytest.raises(SafetyStop, match="step"):
        robot.move_to(HOME)


def test_non_unit_quaternion_is_a_value_error_and_a_safety_stop(
    emulator, connect, monkeypatch
) -> None:
    """A malformed orientation is a bad argument and a refused target: nothing is written."""
    robot = connect(emulator.address)
    writes = count_writes(robot, monkeypatch)
    with pytest.raises(InvalidTarget, match="unit length") as caught:
        robot.move_to(Pose(900.0, 0.0, 600.0, (1.0, 1.0, 0.0, 0.0)))
    assert isinstance(caught.value, ValueError) and isinstance(caught.value, SafetyStop)
    assert writes == []


def test_link_config_and_limits_name_bad_values() -> None:
    """A bad timeout or step limit is refused on construction, the field named."""
    with pytest.raises(ConfigError, match="ack_timeout_s"):
        LinkConfig(url="x", ack_timeout_s=0)
    with pytest.raises(ConfigError, match="max_step_mm"):
        Limits(max_step_mm=-1)
    with pytest.raises(ConfigError, match=r"workspace_min_mm\[2\]"):
        Limits(workspace_min_mm=(0, 0, 10), workspace_max_mm=(1, 1, 10))


@pytest.mark.parametrize("setting", [{"bytesize": 24}, {"bytesize": 9}, {"stopbits": 0},
                                     {"stopbits": 3}, {"parity": "X"}])
def test_serial_settings_pyserial_would_refuse_are_config_errors(setting: dict[str, object]):
    """A byte size, stop bits or parity no UART has is named before the port is opened."""
    with pytest.raises(ConfigError, match=next(iter(setting))):
        LinkConfig(url="x", **setting)  # type: ignore[arg-type]


def test_every_serial_setting_pyserial_takes_is_accepted():
    """Each byte size and stop-bit count pyserial accepts passes the check."""
    for bytesize in (5, 6, 7, 8):
        for stopbits in (1, 1.5, 2):
            LinkConfig(url="x", bytesize=bytesize, stopbits=stopbits)


def test_a_non_finite_reported_position_cannot_bypass_the_step_limit(
    emulator, connect, monkeypatch
) -> None:
    """A controller reporting NaN as its target made every step NaN, and NaN > limit is False.

    The step check now refuses anything not provably within the limit. (The
    reference is the controller's commanded target, read with READ_TARGET.)
    """
    from forcelearn.protocols.computer_link import messages

    real = messages.parse_pose

    def nan_target(body: bytes) -> tuple[tuple[float, float, float], tuple[float, ...]]:
        _, quaternion = real(body)
        return (math.nan,) * 3, quaternion

    monkeypatch.setattr(messages, "parse_pose", nan_target)
    robot = connect(emulator.address, limits=TIGHT)
    writes = count_writes(robot, monkeypatch)
    with pytest.raises(SafetyStop, match="step of nan"):
        robot.move_to(HOME.moved(dz_mm=-1.0))
    assert writes == []
    assert emulator.move_count == 0
