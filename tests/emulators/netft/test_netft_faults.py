"""Every wire fault of the emulated box, and the driver's accounting and typed errors for it."""

from __future__ import annotations

import socket

import pytest
from netft_support import config_for, start

from forcelearn.drivers.netft import NetFtSensor
from forcelearn.emulators.netft import NetFtEmulator, NetFtFaults
from forcelearn.errors import SensorBusError, SensorFault, SensorRebooted, SensorStale
from forcelearn.protocols.netft import Record


def rewrite(order: list[int]):
    """A records hook sending the records whose rdt_sequence is listed, in that order."""
    def hook(records: list[Record]) -> list[Record]:
        by_seq = {r.rdt_sequence: r for r in records}
        return [by_seq[s] for s in order if s in by_seq] if len(records) == 8 else records
    return hook


def test_lost_records_are_counted_and_leave_counter_gaps(emulator: NetFtEmulator) -> None:
    """Records 3 and 5 of 8 dropped: counters skip 2 and 4, lost = 2; 2 more are asked for."""
    emulator.records_hook = rewrite([1, 2, 4, 6, 7, 8])
    with NetFtSensor(config_for(emulator)) as sensor:
        samples = sensor.read_many(8)
        stats = sensor.stats
    assert [s.counter for s in samples] == [0, 1, 3, 5, 6, 7, 8, 9]
    assert (stats.records, stats.lost, stats.duplicates, stats.out_of_order) == (8, 2, 0, 0)
    assert stats.requests == 2  # a start for 8, then one for the 2 missing


def test_duplicated_and_reordered_records(emulator: NetFtEmulator) -> None:
    """3 sent twice, 6 after 7: the copy and the late one are dropped and counted."""
    emulator.records_hook = rewrite([1, 2, 3, 3, 4, 5, 7, 6, 8])
    with NetFtSensor(config_for(emulator)) as sensor:
        samples = sensor.read_many(8)
        stats = sensor.stats
    assert [s.counter for s in samples] == [0, 1, 2, 3, 4, 6, 7, 8]
    assert (stats.duplicates, stats.out_of_order, stats.lost) == (1, 1, 0)


def test_random_faults_match_the_emulators_own_count() -> None:
    """Seeded drops, duplicates and swaps: the driver counts exactly what the box did."""
    faults = NetFtFaults(drop_probability=0.05, duplicate_probability=0.05,
                         reorder_probability=0.05)
    with start(faults=faults, seed=3) as emu, NetFtSensor(config_for(emu)) as sensor:
        samples = sensor.read_many(3000)
        emu.set_faults(NetFtFaults())
        sensor.read_many(1)  # drains what was left of the last faulty request
        stats, done = sensor.stats, emu.stats.faults
    assert done.dropped > 50 and done.duplicated > 50 and done.reordered > 50
    assert stats.lost == done.dropped
    assert stats.duplicates == done.duplicated
    assert stats.out_of_order == done.reordered
    assert len(samples) == 3000
    assert stats.records == 3001


def test_a_silent_box_raises_sensor_stale(emulator: NetFtEmulator) -> None:
    """No record for two requests in a row is SensorStale (the robot must stop)."""
    with NetFtSensor(config_for(emulator, stale_timeout_s=0.1)) as sensor:
        sensor.read()
        emulator.set_faults(NetFtFaults(silent=True))
        with pytest.raises(SensorStale, match="two requests"):
            sensor.read_many(10)
        emulator.set_faults(NetFtFaults())
        assert len(sensor.read_many(10)) == 10  # it speaks again: reading resumes


def test_a_status_error_is_a_typed_fault(emulator: NetFtEmulator) -> None:
    """A record with status 0x80000001 raises SensorFault carrying the word."""
    with NetFtSensor(config_for(emulator)) as sensor:
        sensor.read()
        emulator.set_faults(NetFtFaults(status=0x80000001))
        with pytest.raises(SensorFault, match="0x80000001") as info:
            sensor.read_many(4)
    assert info.value.status == 0x80000001
    assert sensor.stats.status_errors == 1


def test_a_masked_status_bit_is_ignored(emulator: NetFtEmulator) -> None:
    """Bits outside status_error_mask do not stop reading."""
    emulator.set_faults(NetFtFaults(status=0x1))
    with NetFtSensor(config_for(emulator, status_error_mask=0xFFFFFFFE)) as sensor:
        assert len(sensor.read_many(4)) == 4


def test_a_reboot_restarts_the_sequence_and_loses_the_bias() -> None:
    """Reboot after 10 records: SensorRebooted on every read until reinitialise(), no bias.

    The driver never biases on its own after a reboot (the tool may press): the
    cell biases in free space once it has retracted.
    """
    with start(faults=NetFtFaults(reboot_after_records=10)) as emu, \
            NetFtSensor(config_for(emu, stale_timeout_s=0.2, zero_on_init=True)) as sensor:
        sensor.zero_offsets()
        sensor.read_many(4)
        with pytest.raises(SensorRebooted, match="rebooted") as caught:
            sensor.read_many(10)  # the box reboots at its 10th record, mid-request
        assert caught.value.lost == "software bias"
        emu.set_faults(NetFtFaults())
        with pytest.raises(SensorRebooted):
            sensor.read_many(2)  # reading again does not make it go away
        assert emu.stats.reboots == 1 and sensor.stats.reboots == 1
        calinfo_before, bias_before = emu.stats.http_requests, emu.stats.bias_commands
        sensor.reinitialise()
        assert len(sensor.read_many(5)) == 5
        assert emu.stats.http_requests == calinfo_before + 1  # calibration read again
        assert emu.stats.bias_commands == bias_before  # and not biased
        assert emu.model.software_bias.tolist() == [0.0] * 6


def test_inject_reboot_mid_session(emulator: NetFtEmulator) -> None:
    """inject_reboot() restarts ft_sequence at once; the next read reports the reboot."""
    with NetFtSensor(config_for(emulator)) as sensor:
        sensor.read_many(3)
        emulator.inject_reboot()
        with pytest.raises(SensorRebooted, match="rebooted"):
            sensor.read()
        assert emulator.ft_sequence >= 1


def test_garbage_datagrams_are_counted_not_fatal(emulator: NetFtEmulator) -> None:
    """Datagrams of the wrong size from the box's address are rejected and counted."""
    with NetFtSensor(config_for(emulator)) as sensor:
        sensor.read()
        address = sensor._sock.getsockname()
        emulator._udp.sendto(b"\x00" * 35, address)
        emulator._udp.sendto(b"garbage", address)
        assert len(sensor.read_many(3)) == 3
        assert sensor.stats.rejected["RECORD_SIZE"] == 2


def test_malformed_requests_are_ignored_by_the_box(emulator: NetFtEmulator) -> None:
    """A request with a bad header or an unknown command changes nothing at the box."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.connect((emulator.host, emulator.ports["rdt_port"]))
        sock.send(bytes.fromhex("4321000200000001"))
        sock.send(bytes.fromhex("1234007700000001"))
        with NetFtSensor(config_for(emulator)) as sensor:
            sensor.read()  # synchronises: requests are handled in order
    assert emulator.stats.rejected == 2
    assert emulator.stats.records_generated == 1


def test_no_calibration_service_is_a_bus_error(emulator: NetFtEmulator) -> None:
    """Nobody listening on the calibration port: SensorBusError naming host and port."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        closed_port = probe.getsockname()[1]  # bound, never listening: connections refused
        for source, key in (("tcp", "tcp_port"), ("http", "http_port")):
            config = config_for(emulator, calibration_source=source, **{key: closed_port})
            with pytest.raises(SensorBusError, match=f"127.0.0.1:{closed_port}"), \
                    NetFtSensor(config):
                pass
