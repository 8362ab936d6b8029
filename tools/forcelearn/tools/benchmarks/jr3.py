"""Benchmark: JR3 sync-mode paired samples per second through the virtual CAN bus.

The real driver steps the emulated adapter: each read sends SYNC, the emulator
thread answers it at its next simulated 1 ms loop turn with a force and a
moment frame from the shared physics and its sensor model, and the driver
pairs them. Both ends run in this process (two threads, one GIL), so the
figure is what an emulated training run gets in wall time, not the real
adapter's rate: one sample per 1 ms loop turn, about 1,000/s.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import can

from forcelearn.devices import Pose
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams

TARGET_PER_S = 5000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench jr3``."""
    parser.add_argument("--samples", type=int, default=20_000, help="samples per repeat")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats")
    parser.add_argument("--seed", type=int, default=0, help="emulator noise seed")
    parser.add_argument("--window", type=int, default=16,
                        help="window passed to read_many (default 16; the driver keeps one "
                             "SYNC in flight whatever it is)")


def measure(samples: int, seed: int = 0, window: int = 0) -> float:
    """Return paired samples/s of sync stepping (sponge contact).

    ``window=0``: one ``read()`` per sample (send SYNC, wait for the pair);
    ``window>0``: ``read_many`` (one SYNC in flight too: the adapter answers one per turn).
    """
    channel = f"bench-jr3-{os.getpid()}-{seed}-{time.monotonic_ns()}"
    physics = CellPhysics(Sponge(), Pose(0.0, -8.0, -40.0), tool=ToolParams())
    with Jr3EmulatorNode(physics, channel=channel, seed=seed), \
            can.Bus(interface="virtual", channel=channel) as bus, \
            Jr3CanSensor(bus, Jr3Config(mode="sync", stale_timeout_s=1.0)) as sensor:
        for _ in range(200):  # warm up
            sensor.read()
        start = time.perf_counter()
        if window:
            sensor.read_many(samples, window)
        else:
            for _ in range(samples):
                sensor.read()
        elapsed = time.perf_counter() - start
        if sensor.stats.dropped_samples:
            raise RuntimeError("samples were lost on the virtual bus; the figure is void")
    return samples / elapsed


def run(args: argparse.Namespace) -> int:
    """Print paired samples/s per repeat, median and best, for read() and read_many()."""
    print(f"JR3 sync stepping through the virtual bus, {args.samples} samples x {args.repeats}")
    for label, window in (("read() one SYNC at a time", 0),
                          (f"read_many(window={args.window})", args.window)):
        rates = [measure(args.samples, args.seed + i, window) for i in range(args.repeats)]
        shown = ", ".join(f"{r:,.0f}" for r in rates)
        print(f"  {label}: {shown} /s")
        print(f"    median {statistics.median(rates):,.0f}/s, best {max(rates):,.0f}/s "
              f"(target >= {TARGET_PER_S:,}/s)")
    return 0
