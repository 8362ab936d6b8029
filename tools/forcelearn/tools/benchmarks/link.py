"""``forcelearn bench link``: move-command round trip of the computer link over a pty.

Starts the robot-controller emulator in-process on a pseudo-terminal, opens
the real driver on it, and times ``move_by`` calls (request frame, DLE ACK,
reply frame, DLE ACK) end to end. Prints p50 / p99 / max in microseconds.
The pty has no wire time: on a real 9600-baud line the same exchange takes
about 50 ms (docs/computer-link.md).
"""

from __future__ import annotations

import argparse
import time
from typing import Literal

import numpy as np

from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig
from forcelearn.emulators.computer_link import ComputerLinkEmulator


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the link benchmark."""
    parser.add_argument("--commands", type=int, default=2000, help="move commands timed (>= 1000)")
    parser.add_argument("--warmup", type=int, default=100, help="untimed commands first")
    parser.add_argument("--transport", choices=("pty", "tcp"), default="pty")


def measure(commands: int, warmup: int, transport: Literal["pty", "tcp"] = "pty") -> np.ndarray:
    """Return the round-trip times (s) of ``commands`` MOVE_BY commands."""
    times = np.empty(commands)
    with ComputerLinkEmulator(transport) as emulator, ComputerLinkRobot(
        LinkConfig(url=emulator.address)
    ) as robot:
        for i in range(warmup + commands):
            step = 0.05 if i % 2 else -0.05
            start = time.perf_counter()
            robot.move_by(dz_mm=step)
            if i >= warmup:
                times[i - warmup] = time.perf_counter() - start
        if emulator.move_count != warmup + commands:
            raise RuntimeError(f"emulator counted {emulator.move_count} moves")
    return times


def run(args: argparse.Namespace) -> int:
    """Print the round-trip percentiles."""
    if args.commands < 1000:
        raise SystemExit("--commands must be at least 1000 for a meaningful p99")
    times_us = measure(args.commands, args.warmup, args.transport) * 1e6
    p50, p99 = np.percentile(times_us, [50, 99])
    print(
        f"link move round trip over {args.transport}, {args.commands} commands: "
        f"p50 {p50:.0f} us, p99 {p99:.0f} us, max {times_us.max():.0f} us "
        f"({1e6 / times_us.mean():.0f} commands/s); target p99 < 1000 us"
    )
    return 0
