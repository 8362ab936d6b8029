"""The emulated Net F/T's in-process RDT end: the driver reads what loopback UDP delivers."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
from netft_support import config_for, start

from forcelearn.drivers.netft import NetFtSensor
from forcelearn.emulators.netft import NetFtEmulator, NetFtFaults, NetFtModelParams
from forcelearn.emulators.netft.in_process import InProcessRdtSocket
from forcelearn.emulators.netft.sensor_model import NetFtSensorModel
from forcelearn.errors import SensorBusError, SensorStale
from forcelearn.protocols.netft import Record
from forcelearn.site.config import load_cell_config
from forcelearn.site.kinds import jsonable
from forcelearn.site.netft_kind import NetFtRoute
from forcelearn.site.session import CellSession

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _faults(records: list[Record]) -> list[Record]:
    """Record 3 of each request of 10 or more lost, 5 sent twice, 7 after 8.

    Never the tail's: over UDP a late tail is drained by the next request or
    read by it, as the two threads happen to run.
    """
    if len(records) < 10:
        return records
    out = [r for r in records if r.rdt_sequence != 3]
    for i, record in enumerate(list(out)):
        if record.rdt_sequence == 5:
            out.insert(i, record)
    for i in range(len(out) - 2):
        if out[i].rdt_sequence == 7:
            out[i], out[i + 1] = out[i + 1], out[i]
            break
    return out


def _read(route: Literal["in_process", "udp"]) -> tuple[Any, ...]:
    """Bursts with a record lost, one repeated and two swapped, on one route."""
    with start(seed=5, records_hook=_faults) as emu:
        sock = InProcessRdtSocket(emu) if route == "in_process" else None
        with NetFtSensor(config_for(emu), sock=sock) as sensor:
            samples = [*sensor.read_many(150, window=40), sensor.read()]
            sensor.zero_offsets()
            samples += sensor.read_many(10)
            stats = sensor.stats
        assert stats.lost == stats.duplicates == stats.out_of_order > 0
        return (np.array([s.wrench for s in samples]).tolist(), [s.counter for s in samples],
                stats, emu.stats, jsonable(emu.state_dict()), emu.clock.now_s)


def test_the_in_process_route_reads_what_udp_delivers() -> None:
    """Samples, counters, both sides' counts and the box's state are equal on both routes."""
    assert _read("in_process") == _read("udp")


def test_silence_is_stale_at_once_and_a_stream_is_read_in_process(
        emulator: NetFtEmulator) -> None:
    """A silent box raises SensorStale without waiting; stream mode reads fresh records."""
    emulator.set_faults(NetFtFaults(silent=True))
    quiet = InProcessRdtSocket(emulator)
    with NetFtSensor(config_for(emulator, stale_timeout_s=60.0), sock=quiet) as sensor, \
            pytest.raises(SensorStale):
        sensor.read_many(5)
    emulator.set_faults(NetFtFaults())
    with NetFtSensor(config_for(emulator, mode="stream"),
                     sock=InProcessRdtSocket(emulator)) as sensor:
        first = sensor.read()
        assert len(sensor.read_many(20)) == 20 and sensor.read().counter != first.counter
    assert not emulator.streaming  # stop sent on close


def test_a_closed_end_or_box_is_a_bus_error() -> None:
    """Reading through a closed in-process end, or from a closed emulator, raises SensorBusError."""
    emu = start()
    sock = InProcessRdtSocket(emu)
    sensor = NetFtSensor(config_for(emu), sock=sock)
    sensor.read()
    emu.close()
    with pytest.raises(SensorBusError, match="emulator was closed"):
        sensor.read()
    sensor.close()
    with pytest.raises(RuntimeError, match="closed"):
        InProcessRdtSocket(emu)


def test_the_emulated_cell_gives_the_same_state_on_both_routes() -> None:
    """The netft-cell example: moves and force reads, then every emulator state, per route."""
    config = load_cell_config(EXAMPLES / "netft-cell.toml")

    def session(route: Literal["in_process", "udp"]) -> tuple[list[float], dict[str, Any]]:
        with CellSession(config, seed=4, routes={"netft": NetFtRoute(route)}) as s:
            assert s.cell is not None
            forces = []
            for dz in (-3.0, -3.0, 1.0):
                s.cell.move_to(s.cell.sync().moved(0.0, 0.0, dz))
                forces.append(s.cell.measure_force_n())
            return forces, s.emulator_state()

    assert session("in_process") == session("udp")


def test_a_requests_records_measured_at_once_equal_one_at_a_time() -> None:
    """measure_many gives measure's counts, bias walk and generator state (clipping included)."""
    rng = np.random.default_rng(1)
    wrenches = [rng.normal(size=6) * 50.0 for _ in range(60)]
    dts = [float(v) for v in rng.uniform(-1e-4, 1e-3, 60)]
    params = NetFtModelParams(saturation_fraction=0.2)
    one, many = (NetFtSensorModel(params, np.random.default_rng(3)) for _ in range(2))
    one.software_bias = many.software_bias = np.arange(6.0) * 0.1
    counts = [one.measure(w, dt) for w, dt in zip(wrenches, dts, strict=True)]
    assert counts == many.measure_many(wrenches[:25], dts[:25]) + many.measure_many(
        wrenches[25:], dts[25:])
    assert np.array_equal(one.bias, many.bias)
    assert one.rng.bit_generator.state == many.rng.bit_generator.state
