"""``python -m forcelearn.emulators.egm --remote-port P``: run an emulated EGM controller.

Bind the PC side (the driver) first: the controller sends to it. Prints
``EGM <own port>`` once running, then serves until Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from collections.abc import Sequence

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.controller import (
    DEFAULT_CLOCK_EPOCH_US,
    MODES,
    EgmControllerConfig,
)
from forcelearn.emulators.egm.server import EgmControllerEmulator
from forcelearn.emulators.egm.servo import ServoParams


def main(argv: Sequence[str] | None = None) -> int:
    """Run one emulated controller until interrupted."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.emulators.egm")
    parser.add_argument("--remote-port", type=int, required=True, help="the PC's UDP port")
    parser.add_argument("--version", choices=("rw6", "rw7"), default="rw7")
    parser.add_argument("--time-scale", type=float, default=0.0,
                        help="0: as fast as the PC answers; 1: real time")
    parser.add_argument("--real-pace", action="store_true",
                        help="do not wait for answers (needs --time-scale > 0)")
    parser.add_argument("--comm-timeout-s", type=float, default=1.0)
    parser.add_argument("--control-lag-s", type=float, default=0.020)
    parser.add_argument("--mode", choices=MODES, default="pose",
                        help="EGMSetupUC \\Pose (planned.cartesian) or \\Joint (planned.joints)")
    parser.add_argument("--clock-epoch-us", type=int, default=DEFAULT_CLOCK_EPOCH_US,
                        help="feedBack.time at start, µs since 1970 (default 2026-01-01 UTC)")
    parser.add_argument("--force-control-active", action="store_true",
                        help="RW7 fcActive true (the controller's own Force Control runs)")
    args = parser.parse_args(argv)
    config = EgmControllerConfig(
        version=args.version,
        comm_timeout_s=args.comm_timeout_s,
        servo=ServoParams(control_lag_s=args.control_lag_s),
        mode=args.mode,
        clock_epoch_us=args.clock_epoch_us,
        force_control_active=args.force_control_active,
    )
    emulator = EgmControllerEmulator(
        args.remote_port, clock=SimClock(args.time_scale), config=config,
        lockstep=not args.real_pace,
    )
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with emulator:
        print(f"EGM {emulator.port}", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            done.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())
