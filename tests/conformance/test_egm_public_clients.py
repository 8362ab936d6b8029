"""The emulated EGM controller with the two public Python clients, if they are installed.

``abb-robot-client`` (module ``abb_robot_client.egm``) and ``ABBRobotEGM`` are
not dependencies of forcelearn: each test skips when its client is absent.
Both clients bind all interfaces; here their socket is bound to 127.0.0.1.
Both register ``egm.proto`` in protobuf's default descriptor pool, so they
cannot be imported in one process: each scenario runs in a fresh interpreter
(this file run as a script) and reports what the client saw as JSON.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import socket
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import EgmControllerConfig, EgmControllerEmulator
from forcelearn.emulators.physics.cell import CellPhysics

CLIENTS = ("abb_robot_client.egm", "ABBRobotEGM.egm")
START = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))


class LoopbackSocket(socket.socket):
    """A socket whose wildcard bind becomes a bind to 127.0.0.1."""

    def bind(self, address: Any, /) -> None:
        """Bind to 127.0.0.1 where the client asks for every interface."""
        host, port = address
        super().bind(("127.0.0.1" if host in ("", "0.0.0.0") else host, port))


def open_client(module_name: str) -> Any:
    """The client's EGM object on a free loopback port."""
    module = importlib.import_module(module_name)
    plain = socket.socket
    socket.socket = LoopbackSocket  # type: ignore[misc]
    try:
        return module.EGM(port=0)
    finally:
        socket.socket = plain  # type: ignore[misc]


def drive(client: Any, mode: str, cycles: int, send: Any) -> tuple[Any, Any]:
    """Run ``cycles`` cycles, answering each with ``send(client, first_state)``."""
    port = client.socket.getsockname()[1]
    config = EgmControllerConfig(version="rw7", mode=mode)  # type: ignore[arg-type]
    emulator = EgmControllerEmulator(port, physics=CellPhysics(pose=START), clock=SimClock(),
                                     config=config)
    first = state = None
    try:
        with emulator:
            for _ in range(cycles):
                ok, state = client.receive_from_robot(5.0)
                assert ok
                first = first or state
                send(client, first)
    finally:
        client.socket.close()
    return first, state


def pose_scenario(module_name: str) -> dict[str, Any]:
    """Guide a pose 20 mm along x; report the joints the client read and the x reached."""
    target = np.array([920.0, 0.0, 600.0])

    def send(c: Any, first: Any) -> None:
        c.send_to_robot_cart(target, np.array(START.quaternion))

    first, last = drive(open_client(module_name), "pose", 120, send)
    return {
        "first_joints": [float(j) for j in first.joint_angles],
        "first_planned_joints": [float(j) for j in first.joint_angles_planned],
        "last_joints": [float(j) for j in last.joint_angles],
        "last_x": float(last.robot_message.feedBack.cartesian.pos.x),
    }


def joint_scenario(module_name: str) -> dict[str, Any]:
    """In a Joint session send J1 + 5 deg; report the goal and the joints reached."""
    goal: list[float] = []

    def send(c: Any, first: Any) -> None:
        if not goal:
            goal.extend(float(j) for j in first.joint_angles)
            goal[0] += 5.0
        c.send_to_robot(np.array(goal))

    _, last = drive(open_client(module_name), "joint", 80, send)
    return {"goal": goal, "last_joints": [float(j) for j in last.joint_angles]}


SCENARIOS = {"pose": pose_scenario, "joint": joint_scenario}


def run_scenario(module_name: str, scenario: str) -> dict[str, Any]:
    """Run one scenario in a fresh interpreter (skip if the client is not installed)."""
    if importlib.util.find_spec(module_name.split(".")[0]) is None:
        pytest.skip(f"{module_name.split('.')[0]} is not installed (not a dependency)")
    done = subprocess.run(
        [sys.executable, __file__, module_name, scenario],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert done.returncode == 0, done.stderr
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


@pytest.mark.parametrize("module_name", CLIENTS)
def test_client_reads_six_joints_and_guides_a_pose(module_name: str) -> None:
    """The client's joint angles (feedBack/planned.joints) have 6 values; a pose is reached."""
    seen = run_scenario(module_name, "pose")
    assert len(seen["first_joints"]) == 6 and len(seen["first_planned_joints"]) == 6
    assert not np.allclose(seen["last_joints"], seen["first_joints"])
    assert seen["last_x"] == pytest.approx(920.0, abs=0.01)


@pytest.mark.parametrize("module_name", CLIENTS)
def test_client_guides_the_joints_in_joint_mode(module_name: str) -> None:
    """In a Joint session the client's send_to_robot(joints) moves the six axes there."""
    seen = run_scenario(module_name, "joint")
    assert np.allclose(seen["last_joints"], seen["goal"], atol=0.01)


if __name__ == "__main__":
    print(json.dumps(SCENARIOS[sys.argv[2]](sys.argv[1])))
