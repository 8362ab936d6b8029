"""Carried EGM datagrams: the attached message is exactly what decoding the bytes gives.

Compared by ``repr``: a NaN on the wire stays a NaN, and -0.0 must stay -0.0.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.devices import Pose
from forcelearn.protocols.egm import carried, codec

finite = st.floats(allow_nan=False, width=64)
anything = st.floats(width=64)
poses = st.builds(
    lambda x, y, z, q: Pose(x, y, z, q),
    anything, anything, anything, st.tuples(finite, finite, finite, finite),
)
axes = st.lists(finite, max_size=6).map(tuple)
clocks = st.none() | st.integers(-(1 << 40), (1 << 62))
robots = st.builds(
    codec.RobotMessage,
    seqno=st.integers(0, 1 << 40),
    tm_ms=st.integers(0, 1 << 40),
    feedback=st.none() | poses,
    planned=st.none() | poses,
    joints_deg=axes,
    time_us=clocks,
    planned_joints_deg=axes,
    planned_time_us=clocks,
    motor=st.sampled_from(codec.MotorState),
    mci=st.sampled_from(codec.MciState),
    rapid=st.sampled_from(codec.RapidState),
    convergence_met=st.none() | st.booleans(),
    utilization_pct=st.none() | anything,
    measured_force=st.none() | st.lists(finite, min_size=1, max_size=6).map(tuple),
    fc_active=st.none() | st.booleans(),
)
sensors = st.builds(
    codec.SensorMessage,
    seqno=st.integers(0, 1 << 40),
    tm_ms=st.integers(0, 1 << 40),
    planned=st.none() | poses,
    planned_joints_deg=axes,
)


@settings(max_examples=150, deadline=None)
@given(robots, st.sampled_from(codec.VERSIONS))
def test_a_carried_egm_robot_is_what_decoding_its_bytes_gives(
    message: codec.RobotMessage, version: codec.Version
) -> None:
    """Any EgmRobot an emulator could build: the carried message equals the decoded one."""
    datagram = carried.carry_robot(message, version)
    assert bytes(datagram) == codec.encode_robot(message, version)
    got = carried.received_robot(datagram, version)
    assert got is not None
    assert repr(got) == repr(codec.decode_robot(bytes(datagram), version))


@settings(max_examples=150, deadline=None)
@given(sensors, st.sampled_from(codec.VERSIONS))
def test_a_carried_egm_sensor_is_what_decoding_its_bytes_gives(
    message: codec.SensorMessage, version: codec.Version
) -> None:
    """Any EgmSensor without speedRef: the carried message equals the decoded one."""
    datagram = carried.carry_sensor(message, version)
    assert bytes(datagram) == codec.encode_sensor(message, version)
    got = carried.received_sensor(datagram, version)
    assert got is not None
    assert repr(got) == repr(codec.decode_sensor(bytes(datagram), version))


def test_plain_bytes_and_the_other_version_carry_nothing() -> None:
    """Plain bytes, another version's reader or a speedRef: the receiver decodes."""
    message = codec.SensorMessage(1, 2, Pose(1.0, 2.0, 3.0, (1.0, 0.0, 0.0, 0.0)))
    datagram = carried.carry_sensor(message, "rw6")
    assert carried.received_sensor(bytes(datagram), "rw6") is None
    assert carried.received_sensor(datagram, "rw7") is None
    assert carried.received_robot(datagram, "rw6") is None
    with_speed = carried.carry_sensor(
        codec.SensorMessage(1, 2, None, speed_ref=(0.0,) * 6), "rw6")
    assert carried.received_sensor(with_speed, "rw6") is None


def test_numpy_and_int_values_are_carried_as_the_wire_reads_them() -> None:
    """What an emulator may hold (numpy scalars, ints) is carried as the floats decoded."""
    pose = Pose(np.float64(900.5), 2, np.float64(-3.25), (1, 0, 0, 0))  # type: ignore[arg-type]
    message = codec.RobotMessage(
        seqno=(1 << 32) + 5, tm_ms=7, feedback=pose, planned=pose,
        joints_deg=(np.float64(1.0), 2), time_us=-5, motor=codec.MotorState.ON,
        measured_force=(np.float64(0.5),) * 6, fc_active=True,
    )
    for version in codec.VERSIONS:
        datagram = carried.carry_robot(message, version)
        got = carried.received_robot(datagram, version)
        assert repr(got) == repr(codec.decode_robot(bytes(datagram), version))
