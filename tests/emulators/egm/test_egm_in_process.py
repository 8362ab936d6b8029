"""The in-process EGM controller: the UDP emulator's bytes and times, in the driver's thread."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.drivers.egm.guidance import Guidance
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import (
    EgmControllerConfig,
    EgmControllerEmulator,
    EgmEmulatorBase,
    EgmFaultConfig,
    Fault,
    InProcessEgmController,
)
from forcelearn.emulators.egm.controller import EgmControllerModel
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.errors import GuidanceStopped, LinkError
from forcelearn.protocols.egm import codec
from forcelearn.protocols.egm.carried import Carried
from forcelearn.site.config import load_cell_config
from forcelearn.site.egm_kind import EgmRoute
from forcelearn.site.session import CellSession

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
HOME = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))
DRIVER = EgmConfig(port=0, lockstep=True, watchdog_s=5.0)


def _kwargs(faults: EgmFaultConfig | None = None) -> dict[str, Any]:
    return {
        "physics": CellPhysics(pose=HOME, tool=ToolParams()),  # a weight: a measured force
        "clock": SimClock(),
        "config": EgmControllerConfig(),
        "faults": faults,
    }


def _session(route: str, faults: EgmFaultConfig | None) -> tuple[list[object], EgmEmulatorBase]:
    """Moves, waits and a dwell; return what the driver saw and the emulator."""
    emu: EgmEmulatorBase
    if route == "udp":
        robot = EgmRobot(DRIVER)
        emu = EgmControllerEmulator(robot.port, **_kwargs(faults))
        emu.start()
    else:
        emu = InProcessEgmController(**_kwargs(faults))
        robot = EgmRobot(DRIVER, sock=emu.socket())
    seen: list[object] = []
    try:
        robot.wait_for_session(5.0)
        for dz in (-3.0, 2.0, -1.0):
            robot.move_by(dz_mm=dz)
            seen.append(robot.wait_in_position(timeout_s=1.0, settle_s=0.01))
            seen.append(robot.read_pose())
        seen.append(robot.dwell(0.05))
        status = robot.read_status()
        seen += [status.seqno, status.controller_time_s, status.stats]
        # while the controller waits for the answer to its latest cycle (the UDP
        # route's thread goes on after the driver closes, in wall time)
        seen += [emu.clock.now_s, emu.cycles, emu.model.targets_read, emu.state_dict()]
        # the whole status (the measured force, which the in-process route fills in only
        # for the message a wait ends on) and the checkpoint's bytes of the latest EgmRobot
        seen += [status, robot.state_dict()]
    finally:
        robot.close()
        emu.close()
    return seen, emu


@pytest.mark.parametrize(
    "faults",
    [
        None,
        EgmFaultConfig(lose=Fault(0.2), duplicate=Fault(0.2), reorder=Fault(0.1),
                       lose_reply=Fault(0.1), late_reply=Fault(0.1), after_cycles=3, seed=5),
    ],
    ids=["clean", "every-fault"],
)
def test_the_same_cycles_poses_times_and_counters_as_over_udp(
    faults: EgmFaultConfig | None,
) -> None:
    """Both routes run the same cycle halves: everything the driver sees is equal.

    With faults the UDP emulator's thread runs on through cycles that expect
    no answer (a lost or held-back datagram) while the driver is busy, so its
    cycle count at the end is a race there; the in-process one runs them when
    the driver next reads. What the driver saw is the same on both.
    """
    udp, udp_emu = _session("udp", faults)
    local, local_emu = _session("in_process", faults)
    driver_seen = 10  # the waits' times, poses, seqno, controller time, traffic counters
    assert local[:driver_seen] == udp[:driver_seen]
    if faults is None:
        assert local == udp  # and the controller's cycles, clock and state
    else:  # the faults really fired, the same ones on both routes
        kinds = ("lose", "duplicate", "reorder", "lose_reply", "late_reply")
        assert all(local_emu.faults.fired[k] >= 1 for k in kinds)
        assert all(udp_emu.faults.fired[k] >= 1 for k in kinds)


def test_reading_on_without_answering_leaves_cycles_unanswered_until_comm_timeout() -> None:
    """A PC that never answers: each read is one unanswered cycle; CommTimeout in sim time."""
    emu = InProcessEgmController(
        physics=CellPhysics(pose=HOME), config=EgmControllerConfig(comm_timeout_s=0.1)
    )
    sock = emu.socket()
    states = []
    for _ in range(40):
        data, _ = sock.recvfrom(65535)
        states.append(codec.decode_robot(data, "rw7").mci)
    assert emu.unanswered == 39 and emu.cycles == 40
    assert emu.clock.now_s == pytest.approx(39 * 0.004)
    first_stop = states.index(codec.MciState.STOPPED)
    assert first_stop == 25  # 0.1 s after the last read answer (power-up), at 4 ms cycles
    assert emu.guidance_stopped.is_set()
    emu.close()


def test_a_stopped_guidance_fails_the_driver_as_over_udp() -> None:
    """The driver's own checks see what the controller reports, on this route too."""
    emu = InProcessEgmController(physics=CellPhysics(pose=HOME), clock=SimClock())
    with EgmRobot(DRIVER, sock=emu.socket()) as robot:
        robot.wait_for_session()
        robot.dwell(0.02)  # a restart at cycle 1 would repeat seqno 0: a duplicate
        emu.restart_guidance()
        robot.move_by(dz_mm=-2.0)
        with pytest.raises(GuidanceStopped, match="new EGM session"):
            robot.wait_in_position(timeout_s=1.0)
    emu.close()


def test_one_client_at_a_time_and_a_closed_controller_is_a_link_error() -> None:
    """A second socket is refused while the first is open; closing frees the place."""
    emu = InProcessEgmController(physics=CellPhysics(pose=HOME))
    first = emu.socket()
    with pytest.raises(RuntimeError, match="client already"):
        emu.socket()
    first.close()
    robot = EgmRobot(DRIVER, sock=emu.socket())
    robot.wait_for_session()
    emu.close()
    with pytest.raises(LinkError, match="controller was closed"):
        robot.dwell(0.01)
    robot.close()
    with pytest.raises(RuntimeError, match="closed"):
        emu.socket()


def test_a_given_socket_needs_lockstep() -> None:
    """Real mode answers from a thread over UDP; an in-process end is refused there."""
    emu = InProcessEgmController(physics=CellPhysics(pose=HOME))
    with pytest.raises(ValueError, match="lockstep"):
        EgmRobot(EgmConfig(port=0), sock=emu.socket())
    emu.close()


def test_the_emulated_cell_gives_the_same_state_on_both_routes() -> None:
    """The egm-cell example: moves and force reads, then every emulator state, per route."""
    config = load_cell_config(EXAMPLES / "egm-cell.toml")

    def session(route: Literal["in_process", "udp"]) -> tuple[list[float], dict[str, Any]]:
        with CellSession(config, seed=4, routes={"egm": EgmRoute(route)}) as s:
            assert s.cell is not None
            start = s.cell.sync()
            forces = []
            for dz in (-3.0, -3.0, 1.0):
                s.cell.move_to(s.cell.sync().moved(0.0, 0.0, dz) if forces else
                               start.moved(0.0, 0.0, dz))
                forces.append(s.cell.measure_force_n())
            return forces, s.emulator_state()

    assert session("in_process") == session("udp")


def test_a_deferred_measured_force_is_asked_before_the_cell_moves_on() -> None:
    """The in-process EgmRobot's force, left out until asked, is refused once time moved."""
    physics = CellPhysics(pose=HOME, tool=ToolParams())
    emu = InProcessEgmController(physics=physics, clock=physics.clock)
    sock = emu.socket()
    first, _ = sock.recv_carried()
    assert isinstance(first, Carried) and first.pending is not None
    measured = codec.decode_robot(bytes(first), "rw7").measured_force  # finished now
    assert measured == tuple(float(v) for v in physics.true_wrench()) and any(measured)
    sock.send_carried(b"", None)  # an unreadable answer: the cycle ends, the clock moves on
    second, _ = sock.recv_carried()
    physics.clock.advance(0.001)
    with pytest.raises(RuntimeError, match="moved on"):
        bytes(second)
    emu.close()


def test_the_cycles_at_rest_in_one_jump_are_the_cycles_one_by_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A relaxing, hysteretic, rubbing sponge: every result as with every cycle run in full.

    Presses in, slides, backs off, dwells and reads the force: every force,
    status, checkpoint and emulator state equal. The ramps' cycles (a new
    planned pose each) are jumped as well as those at rest.
    """
    config = load_cell_config(EXAMPLES / "egm-cell.toml")
    sponge = replace(config.emulator.sponge, hysteresis_loss=0.3, friction_coefficient=0.3)
    config = replace(config, emulator=replace(config.emulator, sponge=sponge))

    def session(jump: bool) -> tuple[list[object], int]:
        monkeypatch.setattr(InProcessEgmController, "rests", jump)
        with CellSession(config, seed=4) as s:
            assert s.cell is not None
            robot, seen = s.cell.robot, []
            s.cell.move_in_steps(Pose(900.0, 15.0, 0.0, s.cell.sync().quaternion), 9.5)
            for dy, dz in ((-9.0, 0.0), (-9.0, 0.0), (-2.0, 0.0), (0.0, -1.5), (1.0, 0.0)):
                s.cell.move_to(s.cell.sync().moved(0.0, dy, dz))
                seen += [s.cell.measure_force_n(), robot.dwell(0.2), s.cell.measure_force_n()]
            seen += [robot.read_status(), robot.state_dict(), s.emulator_state()]
            return seen, s.robot_emulator.rested, s.robot_emulator.loop.cycles

    batched: list[int] = []
    rest_through = EgmControllerModel.rest_through

    def counted(model: EgmControllerModel, times: list[float]) -> None:
        batched.append(len(times))
        rest_through(model, times)

    monkeypatch.setattr(EgmControllerModel, "rest_through", counted)
    answered: list[Pose | None] = []
    next_planned = Guidance.next_planned

    def counted_answer(guidance: Guidance) -> Pose | None:
        answered.append(next_planned(guidance))
        return answered[-1]

    monkeypatch.setattr(Guidance, "next_planned", counted_answer)
    jumped, rested, cycles = session(True)
    in_batches = sum(batched)
    one_by_one, none, _ = session(False)
    assert none == 0
    assert cycles - rested < 0.1 * cycles  # the ramps' cycles are jumped too, not only the rests
    assert in_batches > 100  # the cycles at rest (the dwells' ends) run in batches (_rest_batch)
    # the PC's answers at rest were taken in runs (at_rest), not one next_planned each
    assert len(answered) < rested - in_batches // 2
    assert jumped == one_by_one
    forces = jumped[0::3][:5]
    assert max(forces) > 5.0 and forces[-1] < forces[-2]  # pressed in, then unloading


def test_a_batch_at_rest_stops_where_the_seqno_wraps(monkeypatch: pytest.MonkeyPatch) -> None:
    """A dwell at rest across the seqno's wrap: what the driver sees is the cycles one by one's."""
    config = load_cell_config(EXAMPLES / "egm-cell.toml")

    def session(jump: bool) -> tuple[list[object], list[int]]:
        monkeypatch.setattr(InProcessEgmController, "rests", jump)
        batched: list[int] = []
        rest_through = EgmControllerModel.rest_through

        def counted(model: EgmControllerModel, times: list[float]) -> None:
            batched.append(len(times))
            rest_through(model, times)

        monkeypatch.setattr(EgmControllerModel, "rest_through", counted)
        with CellSession(config, seed=4) as s:
            assert s.cell is not None
            robot, emu, seen = s.cell.robot, s.robot_emulator, []
            s.cell.move_to(s.cell.sync().moved(0.0, 0.0, -2.0))
            seen.append(robot.dwell(0.5))  # at rest: batches
            wrap = 0xFFFFFFFF - 40  # the controller's seqno 40 cycles before it wraps
            emu.loop.model._seqno = wrap  # (its next EgmRobot's), and the driver's latest one
            guidance = robot._guidance
            assert guidance.latest is not None
            guidance.latest = replace(guidance.latest, seqno=wrap - 1)
            try:
                seen.append(robot.dwell(0.5))
            except GuidanceStopped as exc:  # seqno 0 looks like a restart to the driver
                seen.append(repr(exc))
            seen += [robot.read_status(), robot.state_dict(), s.emulator_state()]
        return seen, batched

    jumped, batched = session(True)
    one_by_one, none = session(False)
    assert none == [] and len(batched) >= 2 and max(batched) > 40
    assert jumped == one_by_one


def test_the_moving_cycles_in_runs_are_the_cycles_one_by_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The default foam, pressed, slid and left (a pass ends): all as every cycle in full.

    The cycles of the moving arm run in runs (``run_cycle``, the cell's side at the
    end); every force, status, checkpoint and emulator state equals the cycles one by one.
    """
    config = load_cell_config(EXAMPLES / "egm-cell.toml")

    def session(jump: bool) -> tuple[list[object], int]:
        monkeypatch.setattr(InProcessEgmController, "rests", jump)
        with CellSession(config, seed=4) as s:
            assert s.cell is not None
            robot, seen = s.cell.robot, []
            s.cell.move_in_steps(Pose(900.0, 15.0, 0.0, s.cell.sync().quaternion), 9.5)
            for dy, dz in ((-9.0, 0.0), (-9.0, 0.0), (0.0, -2.0), (9.0, 0.0), (9.0, 0.0),
                           (9.0, 0.0), (9.0, 0.0), (-9.0, 0.0)):
                s.cell.move_to(s.cell.sync().moved(0.0, dy, dz))
                seen += [s.cell.measure_force_n(), robot.dwell(0.1), s.cell.measure_force_n()]
            sponge = s.robot_emulator.loop.model.physics.environment
            seen += [robot.read_status(), robot.state_dict(), s.emulator_state(),
                     getattr(sponge, "passes", None)]
            return seen, s.robot_emulator.rested

    runs: list[float] = []
    run_cycle = EgmControllerModel.run_cycle

    def counted(model: EgmControllerModel, t_s: float, target: Pose) -> tuple[Pose, bool] | None:
        runs.append(t_s)
        return run_cycle(model, t_s, target)

    monkeypatch.setattr(EgmControllerModel, "run_cycle", counted)
    alone: list[float] = []
    follow_cycle = EgmControllerModel.follow_cycle

    def counted_alone(model: EgmControllerModel, target: Pose, t_s: float) -> Pose:
        alone.append(t_s)
        return follow_cycle(model, target, t_s)

    monkeypatch.setattr(EgmControllerModel, "follow_cycle", counted_alone)
    jumped, rested = session(True)
    in_runs, one_at_a_time = len(runs), len(alone)
    one_by_one, none = session(False)
    assert none == 0 and rested > 0
    assert in_runs > 200  # the moving arm's cycles ran in runs, the ramps' too
    assert one_at_a_time < in_runs / 20
    assert jumped == one_by_one
    assert jumped[-1] is not None and jumped[-1] >= 1  # the tool left the foam: a pass ended
