"""Pure session rules of the driver: sessions, seqno gaps, duplicates, reordering, the ramp."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.drivers.egm.guidance import Guidance
from forcelearn.errors import GuidanceStopped, ProtocolError
from forcelearn.protocols.egm import codec

DOWN = (0.0, 1.0, 0.0, 0.0)
HOME = Pose(900.0, 0.0, 600.0, DOWN)


def robot(seqno: int, pose: Pose = HOME, **kw: object) -> bytes:
    """An RW7 EgmRobot datagram of cycle ``seqno`` (4 ms cycles), guidance running."""
    values = dict(
        seqno=seqno, tm_ms=4 * seqno, feedback=pose, planned=pose, time_us=4000 * seqno,
        motor=codec.MotorState.ON, mci=codec.MciState.RUNNING, rapid=codec.RapidState.RUNNING,
    )
    values.update(kw)
    return codec.encode_robot(codec.RobotMessage(**values), "rw7")  # type: ignore[arg-type]


def test_session_start_seqno_gaps_duplicates_and_reordering() -> None:
    """Session start seqno gaps duplicates and reordering."""
    g = Guidance(EgmConfig(port=0))
    assert g.on_datagram(robot(0)) is True
    assert g.stats.sessions == 1 and g.target == HOME == g.planned
    first = codec.decode_sensor(g.reply(), "rw7")
    assert first.seqno == 0 and first.planned == HOME and first.tm_ms == 0
    assert g.on_datagram(robot(1))
    assert codec.decode_sensor(g.reply(), "rw7").seqno == 1
    assert not g.on_datagram(robot(1))  # duplicate: not answered
    assert g.on_datagram(robot(4))  # 2 and 3 missing
    assert not g.on_datagram(robot(3))  # arrives late: ignored, newer feedback kept
    assert g.latest is not None and g.latest.seqno == 4
    s = g.stats
    assert (s.received, s.duplicates, s.missed, s.out_of_order) == (5, 1, 2, 1)


def test_seqno_zero_starts_a_new_session_and_holds_where_the_robot_is() -> None:
    """Seqno zero starts a new session and holds where the robot is."""
    g = Guidance(EgmConfig(port=0))
    g.on_datagram(robot(0))
    for k in range(1, 4):
        g.on_datagram(robot(k))
        g.reply()
    g.target = HOME.moved(dz_mm=-5)
    elsewhere = HOME.moved(dx_mm=3)
    assert g.on_datagram(robot(0, elsewhere))
    assert g.stats.sessions == 2 and g.session == 2
    assert g.target == elsewhere == g.planned
    assert codec.decode_sensor(g.reply(), "rw7").seqno == 0


def test_planned_pose_ramps_at_the_set_speed() -> None:
    """Planned pose ramps at the set speed."""
    g = Guidance(EgmConfig(port=0, speed_mm_s=50.0))
    g.on_datagram(robot(0))
    g.target = HOME.moved(dz_mm=-1.0)
    zs = []
    for k in range(1, 8):
        g.on_datagram(robot(k))
        zs.append(codec.decode_sensor(g.reply(), "rw7").planned.z_mm)  # type: ignore[union-attr]
    np.testing.assert_allclose(np.diff([600.0, *zs])[:5], -0.2)  # 50 mm/s x 4 ms
    assert zs[-1] == pytest.approx(599.0)


def test_states_that_stop_guidance_are_errors() -> None:
    """States that stop guidance are errors."""
    g = Guidance(EgmConfig(port=0))
    g.on_datagram(robot(0))
    g.require_running()
    g.on_datagram(robot(1, mci=codec.MciState.STOPPED, rapid=codec.RapidState.STOPPED))
    with pytest.raises(GuidanceStopped, match="EGM STOPPED"):
        g.require_running()


def test_a_session_needs_a_cartesian_feedback_pose() -> None:
    """A session needs a cartesian feedback pose."""
    g = Guidance(EgmConfig(port=0))
    with pytest.raises(ProtocolError, match=r"\\Pose"):
        g.on_datagram(robot(0, feedback=None))


def test_controller_time_counts_whole_microseconds_from_the_first_message() -> None:
    """feedBack.time is µs since 1970: waits use differences from the first one, exact to 1 µs.

    As float seconds since 1970 the 4 ms steps would carry errors of about 1e-7 s,
    more than the waits' 1e-9 s tolerance.
    """
    epoch = 1_767_225_600_000_000  # 2026-01-01T00:00:00Z
    g = Guidance(EgmConfig(port=0))
    g.on_datagram(robot(0, time_us=epoch + 12_000))
    assert g.controller_time_s() == 0.0 and g.controller_clock_us() == epoch + 12_000
    for k in range(1, 2500):
        g.on_datagram(robot(k, time_us=epoch + 12_000 + 4000 * k))
    assert g.controller_time_s() == pytest.approx(0.004 * 2499, abs=1e-12)
    restored = Guidance(EgmConfig(port=0))
    restored.load_state_dict(g.state_dict())
    assert restored.controller_time_s() == g.controller_time_s()
