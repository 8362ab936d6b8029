"""EGM codec: golden bytes for RW6 and RW7, round trips, version evidence, broken datagrams."""

from __future__ import annotations

import pytest

from forcelearn.devices import Pose
from forcelearn.errors import EgmVersionMismatch, ProtocolError
from forcelearn.protocols.egm import codec

DOWN = (0.0, 1.0, 0.0, 0.0)
ROBOT = codec.RobotMessage(
    seqno=7,
    tm_ms=28,
    feedback=Pose(900.0, 0.0, 600.0, DOWN),
    planned=Pose(900.0, 0.0, 599.5, DOWN),
    time_us=28_000,
    motor=codec.MotorState.ON,
    mci=codec.MciState.RUNNING,
    rapid=codec.RapidState.RUNNING,
    convergence_met=True,
    utilization_pct=5.0,
    measured_force=(0.0, -2.5, 0.0, 0.0, 0.0, 0.0),
    fc_active=False,
)
SENSOR = codec.SensorMessage(3, 28, Pose(900.0, 0.0, 599.5, DOWN))

# header 0a 06 | seqno 08 07 | tm 10 1c | mtype DATA 18 02
HEADER = "0a060807101c1802"
BODY = (
    "124d12430a1b090000000000208c40110000000000000000190000000000c08240122409000000000000"
    "000011000000000000f03f1900000000000000002100000000000000002206080010e0da011a4512430a"
    "1b090000000000208c40110000000000000000190000000000bc8240122409000000000000000011000000"
    "000000f03f190000000000000000210000000000000000220208012a0208033001420208024a"
)
UTILIZATION = "510000000000001440"  # field 10, fixed64: 5.0
GOLDEN = {
    # RW6 measuredForce: 4a 36, then six doubles as field 1 (09 + 8 bytes each)
    "rw6": HEADER + BODY + "36" + "09" + "0000000000000000" + "09" + "00000000000004c0"
    + ("09" + "0000000000000000") * 4 + UTILIZATION,
    # RW7 measuredForce: 4a 38, fcActive=false (08 00), then six doubles as field 2 (11 ...)
    "rw7": HEADER + BODY + "38" + "0800" + "11" + "0000000000000000" + "11" + "00000000000004c0"
    + ("11" + "0000000000000000") * 4 + UTILIZATION,
}
GOLDEN_SENSOR = (
    "0a060803101c1803124512430a1b090000000000208c40110000000000000000190000000000bc8240"
    "122409000000000000000011000000000000f03f190000000000000000210000000000000000"
)


@pytest.mark.parametrize("version", codec.VERSIONS)
def test_robot_message_golden_bytes_and_round_trip(version: codec.Version) -> None:
    """Robot message golden bytes and round trip."""
    data = codec.encode_robot(ROBOT, version)
    assert data.hex() == GOLDEN[version]
    decoded = codec.decode_robot(data, version)
    rw6_view = ROBOT.__class__(**{**ROBOT.__dict__, "fc_active": None})  # RW6 has no fcActive
    expected = ROBOT if version == "rw7" else rw6_view
    assert decoded == expected


@pytest.mark.parametrize("version", codec.VERSIONS)
def test_sensor_message_golden_bytes_and_round_trip(version: codec.Version) -> None:
    """Sensor message golden bytes and round trip."""
    data = codec.encode_sensor(SENSOR, version)
    assert data.hex() == GOLDEN_SENSOR  # the fields guidance uses are the same in RW6 and RW7
    assert codec.decode_sensor(data, version) == SENSOR


@pytest.mark.parametrize("version", codec.VERSIONS)
def test_joints_clocks_and_speed_ref_round_trip_with_their_field_numbers(
    version: codec.Version,
) -> None:
    """feedBack/planned joints and times, planned.joints and speedRef: ABB's field numbers.

    EgmFeedBack/EgmPlanned: joints = 1, time = 4 (EgmClock sec = 1, usec = 2);
    EgmSensor: planned = 2, speedRef = 3 (EgmSpeedRef joints = 1, cartesians = 2).
    """
    clock_us = 1_767_225_600_004_000  # 2026-01-01T00:00:00.004Z
    robot = codec.RobotMessage(
        seqno=1, tm_ms=4, feedback=ROBOT.feedback, planned=ROBOT.planned,
        joints_deg=(0.0, 37.5, -109.0, 0.0, 180.0, 180.0), time_us=clock_us,
        planned_joints_deg=(0.5, 37.0, -108.0, 0.0, 179.0, 180.0),
        planned_time_us=clock_us + 20_000,
    )
    decoded = codec.decode_robot(codec.encode_robot(robot, version), version)
    assert decoded == robot and decoded.time_s == pytest.approx(1_767_225_600.004)
    pb = codec.proto_module(version).EgmRobot.FromString(codec.encode_robot(robot, version))
    assert (pb.feedBack.time.sec, pb.feedBack.time.usec) == (1_767_225_600, 4000)
    assert list(pb.planned.joints.joints) == list(robot.planned_joints_deg)
    sensor = codec.SensorMessage(
        2, 4, None, planned_joints_deg=(1.0, 2.0, -90.0, 0.0, 90.0, 0.0),
        speed_ref=(50.0, 0.0, 0.0, 0.0, 0.0, 10.0), speed_ref_joints_deg_s=(1.0,) * 6,
    )
    data = codec.encode_sensor(sensor, version)
    assert codec.decode_sensor(data, version) == sensor
    fields = {number: value for number, _, value in codec.wire_fields(data)}
    speed = {number: value for number, _, value in codec.wire_fields(fields[3])}
    assert set(speed) == {1, 2}
    assert {number for number, _, _ in codec.wire_fields(fields[2])} == {1}  # joints only


def test_a_parser_of_the_other_version_misreads_force_silently() -> None:
    """Why the driver checks the version: protobuf itself raises nothing."""
    rw7_data = codec.encode_robot(ROBOT, "rw7")
    misread = codec.decode_robot(rw7_data, "rw6")
    assert misread.measured_force == ()  # force lost without any error
    rw6_data = codec.encode_robot(ROBOT, "rw6")
    assert codec.decode_robot(rw6_data, "rw7").measured_force == ()


@pytest.mark.parametrize(("sent", "configured"), [("rw6", "rw7"), ("rw7", "rw6")])
def test_version_mismatch_is_detected_from_the_wire(
    sent: codec.Version, configured: codec.Version
) -> None:
    """Version mismatch is detected from the wire."""
    data = codec.encode_robot(ROBOT, sent)
    assert codec.detect_version(data) == sent
    codec.check_version(data, sent)
    with pytest.raises(EgmVersionMismatch, match=f"robot.version = '{sent}'"):
        codec.check_version(data, configured)


def test_a_message_without_version_evidence_is_accepted_by_both() -> None:
    """A message without version evidence is accepted by both."""
    plain = ROBOT.__class__(**{**ROBOT.__dict__, "measured_force": None, "fc_active": None})
    data = codec.encode_robot(plain, "rw6")
    assert codec.detect_version(data) is None
    for version in codec.VERSIONS:
        codec.check_version(data, version)


def test_broken_datagrams_raise_protocol_error() -> None:
    """Broken datagrams raise protocol error."""
    data = codec.encode_robot(ROBOT, "rw7")
    with pytest.raises(ProtocolError):
        codec.decode_robot(data[:-3], "rw7")
    with pytest.raises(ProtocolError):
        list(codec.wire_fields(data[:-3]))
    with pytest.raises(ProtocolError, match="mtype"):
        codec.decode_robot(codec.encode_sensor(SENSOR, "rw7"), "rw7")
    with pytest.raises(ProtocolError, match="header"):
        codec.decode_robot(b"", "rw7")
