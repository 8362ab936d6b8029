"""``python -m forcelearn.emulators.netft``: serve an emulated Net F/T on 127.0.0.1.

Prints one JSON line with the bound ports, then serves until stdin closes,
Ctrl-C or SIGTERM::

    {"host": "127.0.0.1", "rdt_port": 49152, "tcp_port": 49151, "http_port": 40211}
"""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import sys
from collections.abc import Sequence

from forcelearn.devices import Pose
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.netft.server import DEFAULT_RDT_RATE_HZ, start_emulated_netft
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams


def main(argv: Sequence[str] | None = None) -> int:
    """Run the emulated box until stdin closes or the process is interrupted."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.emulators.netft")
    parser.add_argument("--rdt-port", type=int, default=None,
                        help="UDP RDT port (default 49152 where free; 0: any free port)")
    parser.add_argument("--tcp-port", type=int, default=None,
                        help="READCALINFO port (default 49151 where free; 0: any free port)")
    parser.add_argument("--http-port", type=int, default=0, help="web port (0: any free port)")
    parser.add_argument("--rate-hz", type=float, default=DEFAULT_RDT_RATE_HZ,
                        help="RDT rate, records/s (at most 7000)")
    parser.add_argument("--rdt-buffer-size", type=int, default=1,
                        help="records per datagram of buffered streaming, 1..40 (comrdtbsiz)")
    parser.add_argument("--time-scale", type=float, default=0.0,
                        help="pace: 0 as fast as possible, 1 real time")
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument("--contact", action="store_true",
                        help="tool pressed 8 mm into the sponge (default: free space, no tool)")
    args = parser.parse_args(argv)
    physics = (CellPhysics(Sponge(), Pose(0.0, -8.0, -40.0), tool=ToolParams())
               if args.contact else CellPhysics())
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        emulator = start_emulated_netft(
            physics, SimClock(args.time_scale), args.seed, rdt_port=args.rdt_port,
            tcp_port=args.tcp_port, http_port=args.http_port, rdt_rate_hz=args.rate_hz,
            rdt_buffer_size=args.rdt_buffer_size,
        )
    except ValueError as exc:  # a rate or buffer size the box cannot have
        parser.error(str(exc))
    with emulator, contextlib.suppress(KeyboardInterrupt):
        print(json.dumps({"host": emulator.host, **emulator.ports}), flush=True)
        sys.stdin.read()  # until the parent closes our stdin
    return 0


if __name__ == "__main__":
    sys.exit(main())
