"""``forcelearn bench egm``: the emulated 4 ms EGM loop at real-time pace over loopback UDP.

Starts the EGM controller emulator in-process at real pace (``time_scale`` 1,
no lockstep: every cycle is sent at its wall time and the latest answer
received before the next cycle is read, as on a real controller) and the real
driver in real mode (its receive thread answers every EgmRobot at once). The
host thread meanwhile moves the robot 1 mm back and forth. Prints, from the
emulator's wall-clock record:

* cycle period p50 / p99 and jitter (|period - 4 ms|) p50 / p99 / max;
* reply latency: from sending an EgmRobot to receiving the driver's EgmSensor
  (both UDP hops, the driver's decode/encode and thread wake-ups), p50 / p99 / max.

Both ends run in one process (two threads, one GIL): the figures are this
host's, not the robot controller's (4.032 ms on a real robot, manual p.17).
"""

from __future__ import annotations

import argparse
from contextlib import closing

import numpy as np

from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import EgmControllerEmulator

PERIOD_S = 0.004


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench egm``."""
    parser.add_argument("--cycles", type=int, default=2500, help="cycles timed (>= 1000; 10 s)")
    parser.add_argument("--warmup", type=int, default=250, help="untimed cycles first")


def measure(cycles: int, warmup: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (cycle periods, reply latencies) in seconds over ``cycles`` timed cycles."""
    config = EgmConfig(port=0, lockstep=False, watchdog_s=1.0, stale_after_s=1.0)
    with closing(EgmRobot(config)) as robot:  # opened below, once its port is served
        emulator = EgmControllerEmulator(
            robot.port, clock=SimClock(time_scale=1.0), lockstep=False, record_timing=True
        )
        with emulator:
            robot.wait_for_session(5.0)
            step = 1.0
            while emulator.cycles < warmup + cycles + 1:
                robot.move_by(dz_mm=step)
                step = -step
                robot.dwell(0.1)
            timing = emulator.timing
        assert timing is not None
        sends = np.asarray(timing.send_s[warmup : warmup + cycles + 1])
        latencies = np.asarray(timing.reply_latency_s[warmup : warmup + cycles])
    return np.diff(sends), latencies


def run(args: argparse.Namespace) -> int:
    """Print the period, jitter and reply-latency percentiles."""
    if args.cycles < 1000:
        raise SystemExit("--cycles must be at least 1000 for a meaningful p99")
    periods, latencies = measure(args.cycles, args.warmup)
    period_us, latency_us = periods * 1e6, latencies * 1e6
    jitter_us = np.abs(period_us - PERIOD_S * 1e6)
    p = np.percentile
    print(f"EGM emulated loop at real pace over loopback UDP, {args.cycles} cycles of 4 ms")
    print(f"  cycle period: p50 {p(period_us, 50):.0f} us, p99 {p(period_us, 99):.0f} us, "
          f"mean {period_us.mean():.1f} us")
    print(f"  jitter |period - 4 ms|: p50 {p(jitter_us, 50):.0f} us, "
          f"p99 {p(jitter_us, 99):.0f} us, max {jitter_us.max():.0f} us")
    print(f"  driver reply latency (EgmRobot sent -> EgmSensor received): "
          f"p50 {p(latency_us, 50):.0f} us, p99 {p(latency_us, 99):.0f} us, "
          f"max {latency_us.max():.0f} us ({len(latency_us)} replies)")
    return 0
