"""The Net F/T driver against the emulated box over loopback: calibration, values, time, resume."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from netft_support import QUIET, config_for, contact_physics, start

from forcelearn.devices import BatchForceSensor, ForceSensor, Pose
from forcelearn.drivers.netft import NetFtSensor, open_netft_sensor
from forcelearn.drivers.netft.traffic_log import read_traffic_log
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.netft import NetFtEmulator, NetFtModelParams
from forcelearn.errors import ConfigError, SensorProtocolError
from forcelearn.protocols.netft import CalInfo, Record, decode_request, encode_calinfo_request


@pytest.mark.parametrize("source", ["tcp", "http"])
def test_calibration_over_tcp_and_http(source: str) -> None:
    """Both services give the model's counts per unit and units; HTTP also rate and ranges."""
    model = NetFtModelParams(counts_per_force=500_000, counts_per_torque=2_000,
                             torque_unit="N-mm")
    with start(model=model, rdt_rate_hz=1000) as emu, \
            NetFtSensor(config_for(emu, calibration_source=source)) as sensor:
        cal = sensor.calibration
        assert (cal.counts_per_force, cal.counts_per_torque) == (500_000, 2_000)
        assert (cal.force_unit, cal.torque_unit, cal.source) == ("N", "N-mm", source)
        assert np.allclose(cal.si_per_count, [2e-6] * 3 + [5e-7] * 3)
        if source == "http":
            assert cal.rdt_rate_hz == 1000
            assert cal.ranges_si == pytest.approx(model.ranges)
        assert isinstance(sensor, ForceSensor) and isinstance(sensor, BatchForceSensor)
    assert emu.stats.calinfo_requests == (source == "tcp")
    assert emu.stats.http_requests == (source == "http")


def test_configured_value_must_agree_with_the_box(emulator: NetFtEmulator) -> None:
    """A config expecting 1,000,000 counts/N refuses a box reporting 500,000, naming both."""
    emulator.xml_fields["cfgcpf"] = "500000"
    sensor = NetFtSensor(config_for(emulator, counts_per_force=1_000_000))
    with pytest.raises(ConfigError, match=r"counts_per_force = 1000000.*reports 500000"):
        sensor.initialise()
    sensor.close()
    with pytest.raises(ConfigError, match="rdt_rate_hz"):
        open_netft_sensor(config_for(emulator, rdt_rate_hz=1000.0))


def test_nonsense_calibration_from_the_wire_is_refused(emulator: NetFtEmulator) -> None:
    """Zero counts per force over TCP, a negative one over HTTP: never used as a scale."""
    emulator.calinfo = CalInfo(2, 3, 0, 1_000_000)
    with pytest.raises(SensorProtocolError, match="counts_per_force"):
        open_netft_sensor(config_for(emulator, calibration_source="tcp"))
    emulator.xml_fields["cfgcpt"] = "-1000000"
    with pytest.raises(SensorProtocolError, match="counts_per_torque"):
        open_netft_sensor(config_for(emulator, calibration_source="http"))


def test_values_quantisation_bias_and_saturation() -> None:
    """Quiet model: readings equal the physics to one count; overload is flagged; bias zeroes."""
    physics = contact_physics(8.0)
    with start(physics, model=QUIET) as emu, NetFtSensor(config_for(emu)) as sensor:
        sample = sensor.read()
        assert np.allclose(sample.wrench, physics.true_wrench(), atol=1e-6)
        assert sample.saturated == (False,) * 6
        physics.set_pose(Pose(0.0, -42.0, -40.0))  # through the foam onto its backing
        pressed = sensor.read()
        assert pressed.saturated[1] and not pressed.saturated[0]
        assert pressed.wrench[1] == pytest.approx(QUIET.ranges[1])  # the gauges clip
        physics.set_pose(Pose(0.0, -8.0, -40.0))
        sensor.zero_offsets()
        assert np.allclose(sensor.read_many(5)[-1].wrench, 0.0, atol=1e-6)
        assert emu.stats.bias_commands == 1


def test_burst_spends_simulated_time_at_the_rdt_rate() -> None:
    """N records at 1 kHz move the clock by (N - 1) ms; the next burst starts one period on."""
    clock = SimClock()
    with start(clock=clock, rdt_rate_hz=1000) as emu, NetFtSensor(config_for(emu)) as sensor:
        samples = sensor.read_many(100, 25)
        assert clock.now_s == pytest.approx(0.099)
        assert [s.counter for s in samples] == list(range(100))
        clock.advance_to(0.5)  # the robot moved for a while
        sensor.read_many(10)
        assert clock.now_s == pytest.approx(0.509)
        assert emu.last_sample_s == pytest.approx(0.509)


def test_physics_advance_to_is_called_per_sample_when_present() -> None:
    """A physics with advance_to(t_s) is moved to each record's time before it is sampled."""
    physics = contact_physics()
    times: list[float] = []
    physics.advance_to = times.append  # type: ignore[attr-defined]
    with start(physics, rdt_rate_hz=500) as emu, NetFtSensor(config_for(emu)) as sensor:
        sensor.read_many(4)
    assert times == pytest.approx([0.0, 0.002, 0.004, 0.006])


def test_resume_is_bit_identical() -> None:
    """Emulator and clock state saved after 50 records give the same next 50 records."""
    def run(state: tuple | None) -> tuple[np.ndarray, tuple]:
        clock = SimClock()
        with start(clock=clock, seed=7) as emu, NetFtSensor(config_for(emu)) as sensor:
            if state is not None:
                emu.load_state_dict(state[0])
                clock.load_state_dict(state[1])
            else:
                sensor.read_many(50)
            saved = (emu.state_dict(), clock.state_dict())
            wrench = np.array([s.wrench for s in sensor.read_many(50)])
        return wrench, saved

    first, saved = run(None)
    resumed, _ = run(saved)
    assert np.array_equal(first, resumed)


def test_stream_mode_and_traffic_log(tmp_path, emulator: NetFtEmulator) -> None:
    """Infinite streaming: read() gives fresh records; the log holds the raw datagrams."""
    path = tmp_path / "netft.log"
    with NetFtSensor(config_for(emulator, mode="stream", log_path=str(path))) as sensor:
        first = sensor.read()
        samples = sensor.read_many(200)
        later = sensor.read()
    assert later.counter != first.counter and len(samples) == 200
    logged = list(read_traffic_log(path))
    sent = [decode_request(d.data) for d in logged if d.direction == "tx"]
    assert sent[0].command == 2 and sent[0].sample_count == 0  # start, until stopped
    assert sent[-1].command == 0  # stop on close
    received = [d for d in logged if d.direction == "rx"]
    assert len(received) >= 202 and all(len(d.data) == 36 for d in received)
    assert all(a.time_s <= b.time_s for a, b in itertools.pairwise(logged))


def test_records_hook_sees_the_burst(emulator: NetFtEmulator) -> None:
    """The hook gets each request's records, numbered 1..N; ft_sequence counts on since boot."""
    seen: list[list[Record]] = []
    emulator.records_hook = lambda records: seen.append(list(records)) or records
    with NetFtSensor(config_for(emulator)) as sensor:
        sensor.read_many(3)
        sensor.read_many(2)
    assert [r.rdt_sequence for r in seen[0]] == [1, 2, 3]
    assert [r.rdt_sequence for r in seen[1]] == [1, 2]
    assert [r.ft_sequence for r in seen[1]] == [3, 4]


@pytest.mark.parametrize("service", ["http_port", "tcp_port"])
def test_a_client_hanging_up_mid_reply_prints_no_trace_and_the_box_serves_on(
    emulator: NetFtEmulator, service: str, capfd: pytest.CaptureFixture[str]
) -> None:
    """A driver whose timeout passed closes at once (RST); the box logs it and answers the next."""
    import socket
    import struct
    import time

    request = (b"GET /netftapi2.xml HTTP/1.0\r\n\r\n" if service == "http_port"
               else encode_calinfo_request())
    for _ in range(20):
        client = socket.create_connection(("127.0.0.1", emulator.ports[service]))
        client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        client.sendall(request)
        client.close()
    time.sleep(0.3)
    assert "Traceback" not in capfd.readouterr().err
    with NetFtSensor(config_for(emulator, calibration_source="http")) as sensor:
        assert sensor.calibration.counts_per_force > 0


def test_the_rdt_rate_is_capped_at_the_boxs_7000_per_s() -> None:
    """The Net F/T streams at most 7000 records/s (manual §10); the emulator refuses more."""
    with start(rdt_rate_hz=7000):
        pass
    with pytest.raises(ValueError, match="7000"):
        start(rdt_rate_hz=7001)


@pytest.mark.parametrize("size", [0, 41])
def test_an_rdt_buffer_size_outside_1_to_40_is_refused(size: int) -> None:
    """The box's comrdtbsiz is 1..40 (40 records of 36 bytes fill one Ethernet frame)."""
    with pytest.raises(ValueError, match="rdt_buffer_size"):
        start(rdt_buffer_size=size)


def test_a_buffered_request_that_is_not_whole_buffers_ends_with_a_short_datagram() -> None:
    """Our choice where the manual is silent: N records, the last datagram holds the rest."""
    import socket

    from forcelearn.protocols.netft import Command, Request, decode_datagram, encode_request

    with start(model=QUIET, rdt_buffer_size=4) as emu, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.connect((emu.host, emu.ports["rdt_port"]))
        sock.settimeout(2.0)
        sock.send(encode_request(Request(Command.START_BUFFERED, 10)))
        batches = [decode_datagram(sock.recv(65536)) for _ in range(3)]
        assert emu.wait_handled(1)  # the request's sends (and their counts) are done
        assert emu.stats.datagrams_sent == 3 and emu.stats.records_sent == 10
    assert all(isinstance(b, list) for b in batches)
    sizes = [len(b) for b in batches if isinstance(b, list)]
    seqs = [r.rdt_sequence for b in batches if isinstance(b, list) for r in b]
    assert sizes == [4, 4, 2] and seqs == list(range(1, 11))


@pytest.mark.parametrize("source", ["http", "tcp"])
def test_a_box_that_spells_newton_metres_nm_is_read_and_agrees_with_n_m(source: str) -> None:
    """A box that spells the torque unit "Nm" is read as N-m and agrees with "N-m".

    A live netftapi2.xml (firmware 2.2.59, quoted in a public client's tests) says
    ``<scfgtu>Nm</scfgtu>``; before, the driver refused it as an unknown unit.
    """
    model = replace(QUIET, torque_unit="Nm", counts_per_torque=1_000_000)
    with start(contact_physics(), model=model) as emu, NetFtSensor(
        config_for(emu, calibration_source=source, torque_unit="N-m", zero_on_init=False)
    ) as sensor:
        assert emu.xml_fields["scfgtu"] == "Nm"
        assert sensor.calibration.si_per_count[3:] == pytest.approx([1e-6] * 3)
        assert np.allclose(sensor.read().wrench, emu.physics.true_wrench(), atol=1e-5)
