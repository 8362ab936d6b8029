"""``Surface-v0`` over the in-process routes and over the wire routes gives the same episodes.

The in-process routes (``forcelearn-robot://``, a ``forcelearn-jr3`` bus: the
emulators answer in the driver's thread) carry the same bytes and frames as the
wire routes a real cell's ports are reached by (a pty and a python-can
``virtual`` bus, each emulator on its own thread), so the simulated clock, the
observations and the rewards must agree exactly.
"""

from __future__ import annotations

import can
import numpy as np
import pytest

from forcelearn.emulators.computer_link.serial_port import EmulatedRobotSerial
from forcelearn.emulators.jr3.can_bus import Jr3EmulatorBus
from forcelearn.envs import SurfaceEnv
from forcelearn.site import CellConfig
from forcelearn.site.computer_link_kind import LinkRoute
from forcelearn.site.jr3_kind import Jr3Route

WIRE = {"computer_link": LinkRoute("pty"), "jr3": Jr3Route("virtual")}


def _episodes(config: CellConfig, routes: dict[str, object]) -> tuple[list[bytes], list[type]]:
    """Two episodes (the second after a reset without seed) as bytes, and the transports."""
    env = SurfaceEnv(config, routes=routes)
    actions = np.random.default_rng(7).uniform(-1.0, 1.0, size=(26, 1))
    seen: list[bytes] = []
    try:
        obs, _ = env.reset(seed=5)
        seen.append(obs.tobytes())
        assert env.session is not None
        transports = [type(env.session.robot._port), type(env.session.sensor.bus)]
        for action in actions:
            obs, reward, terminated, truncated, _ = env.step(action)
            seen += [obs.tobytes(), np.float64(reward).tobytes(), bytes((terminated, truncated))]
            if terminated or truncated:
                obs, _ = env.reset()
                seen.append(obs.tobytes())
        seen.append(np.float64(env.session.cell.time_s).tobytes())
    finally:
        env.close()
    return seen, transports


def test_the_in_process_and_the_wire_routes_give_equal_episodes(
    no_probe_config: CellConfig,
) -> None:
    """Observations, rewards, episode ends and the cell's clock agree to the bit."""
    in_process, inner = _episodes(no_probe_config, {})
    wire, outer = _episodes(no_probe_config, WIRE)
    assert inner == [EmulatedRobotSerial, Jr3EmulatorBus]
    assert outer[0] is not EmulatedRobotSerial  # pyserial's own port on the pty
    assert outer[1] is can.interfaces.virtual.VirtualBus
    assert wire == in_process


def test_a_route_option_of_the_wrong_kind_is_refused() -> None:
    """Each kind takes its own route option, and only the routes it has."""
    with pytest.raises(ValueError, match="pty"):
        LinkRoute("udp")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="virtual"):
        Jr3Route("slcan")  # type: ignore[arg-type]
    env = SurfaceEnv(routes={"jr3": LinkRoute("pty")})
    with pytest.raises(TypeError, match="Jr3Route"):
        env.reset(seed=0)
    env.close()
