"""``python -m forcelearn.emulators.computer_link``: serve until Ctrl-C, print the URL."""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
from collections.abc import Sequence

from forcelearn.emulators.computer_link.server import ComputerLinkEmulator
from forcelearn.emulators.physics.arm import ArmConfig


def main(argv: Sequence[str] | None = None) -> int:
    """Run an emulated controller on a pty or 127.0.0.1 TCP until interrupted."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.emulators.computer_link")
    parser.add_argument("--transport", choices=("pty", "tcp"), default="pty")
    parser.add_argument("--port", type=int, default=0, help="TCP port (0: any free one)")
    parser.add_argument("--lag-s", type=float, default=0.0, help="servo time constant, s")
    args = parser.parse_args(argv)
    emulator = ComputerLinkEmulator(
        args.transport, config=ArmConfig(lag_s=args.lag_s), port=args.port
    )
    with emulator:
        print(emulator.address, flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            threading.Event().wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())
