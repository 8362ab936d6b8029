"""Benchmark: Net F/T records per second and delivery latency through loopback UDP.

The real driver reads the emulated box: each ``read_many`` sends a start
request for a burst of records, the emulator samples the shared physics at the
RDT rate on the cell's simulated clock and sends the records, and the driver
checks and scales them. Both ends run in this process (two threads, one GIL),
as in an emulated training run. Two figures:

* **as fast as possible** (``time_scale = 0``): records/s the host sustains.
* **real-time pace** (``time_scale = 1``): the emulator releases each record
  when a real box would (about 1 ms slices at 7 kHz); records/s should equal
  the RDT rate, and the *delivery latency* (the driver's receive time minus
  the moment the emulator called ``sendto``, same monotonic clock) is what
  loopback, the thread hand-over and the driver add. p50 and p99 are printed.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from forcelearn.devices import Pose
from forcelearn.drivers.netft import NetFtConfig, NetFtSensor
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.netft import NetFtEmulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench netft``."""
    parser.add_argument("--records", type=int, default=20_000,
                        help="records per as-fast-as-possible repeat")
    parser.add_argument("--seconds", type=float, default=2.0,
                        help="simulated (= wall) seconds of the real-time-paced run")
    parser.add_argument("--repeats", type=int, default=3, help="repeats of each figure")
    parser.add_argument("--rate-hz", type=float, default=7000.0, help="RDT output rate")
    parser.add_argument("--window", type=int, default=64, help="records per request")
    parser.add_argument("--seed", type=int, default=0, help="emulator noise seed")


def measure(records: int, *, time_scale: float, rate_hz: float, window: int,
            seed: int) -> tuple[float, np.ndarray]:
    """Return (records/s, delivery latencies in s) of one run of ``records`` records."""
    physics = CellPhysics(Sponge(), Pose(0.0, -8.0, -40.0), tool=ToolParams())
    sent_at: list[float] = []
    with NetFtEmulator(physics, SimClock(time_scale), seed=seed, rdt_port=0, tcp_port=0,
                       rdt_rate_hz=rate_hz,
                       on_send=lambda _record: sent_at.append(time.monotonic())) as emu, \
            NetFtSensor(NetFtConfig(host=emu.host, stale_timeout_s=1.0, burst_records=window,
                                    rdt_port=emu.ports["rdt_port"],
                                    tcp_port=emu.ports["tcp_port"],
                                    http_port=emu.ports["http_port"])) as sensor:
        sensor.read_many(200)  # warm up
        first = len(sent_at)
        start = time.perf_counter()
        samples = sensor.read_many(records)
        elapsed = time.perf_counter() - start
        if sensor.stats.lost or sensor.stats.duplicates or sensor.stats.out_of_order:
            raise RuntimeError(f"records were lost on loopback ({sensor.stats}); figure void")
    received = np.array([s.timestamp_s for s in samples])
    latency = received - np.array(sent_at[first:first + records])
    return records / elapsed, latency


def run(args: argparse.Namespace) -> int:
    """Print records/s (as fast as possible and paced) and the paced delivery latency."""
    print(f"Net F/T RDT over loopback UDP, {args.rate_hz:g} Hz, {args.window} records per "
          "request, driver and emulator in one process")
    fast = [measure(args.records, time_scale=0.0, rate_hz=args.rate_hz, window=args.window,
                    seed=args.seed + i)[0] for i in range(args.repeats)]
    print(f"  as fast as possible ({args.records} records): "
          f"{', '.join(f'{r:,.0f}' for r in fast)} records/s; median "
          f"{statistics.median(fast):,.0f}/s")
    paced_records = max(1, round(args.seconds * args.rate_hz))
    for i in range(args.repeats):
        rate, latency = measure(paced_records, time_scale=1.0, rate_hz=args.rate_hz,
                                window=args.window, seed=args.seed + i)
        p50, p99, worst = np.percentile(latency, [50, 99, 100]) * 1e6
        print(f"  real-time pace ({paced_records} records): {rate:,.0f} records/s; delivery "
              f"latency p50 {p50:.0f} us, p99 {p99:.0f} us, max {worst:.0f} us")
    return 0
