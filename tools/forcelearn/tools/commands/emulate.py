"""``forcelearn emulate``: run the emulated cell as its own process, reachable as on site.

Serves the far ends of a robot and a sensor of any kinds
(:class:`~forcelearn.site.EmulatedCell`; ``--robot`` and ``--sensor``, default
the config's kinds), prints where they are and a site config that reaches
them, and serves until SIGINT or SIGTERM. By default the robot-controller
emulator on one pseudo-terminal and the JR3 emulator behind an emulated slcan
(LAWICEL) USB-CAN adapter on a second one; ``--robot egm`` the EGM controller
on loopback UDP toward ``--egm-port``, ``--sensor netft`` the Net F/T box on
its UDP/TCP/HTTP ports. From another shell::

    forcelearn emulate --write-config /tmp/emulated-site.toml
    forcelearn check --config /tmp/emulated-site.toml

``--robot link`` is the old spelling of ``--robot computer_link`` (deprecated).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from forcelearn.atomic import atomic_write_bytes
from forcelearn.site import EmulatedCell, kinds, load_cell_config
from forcelearn.site.kinds import ALIASES

WAIT_SLICE_S = 0.2
"""How often the main thread looks at the stop flag (s)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn emulate``."""
    parser.add_argument(
        "--config", type=Path, help="cell config whose [emulator] tables shape the cell"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (0)")
    parser.add_argument(
        "--write-config", type=Path, metavar="FILE", help="also write the site config to FILE"
    )
    parser.add_argument(
        "--link-dir", type=Path, metavar="DIR", default=default_link_dir(),
        help="folder for the stable pty symlinks ('robot', 'jr3-slcan') named in the site "
        f"config (default {default_link_dir()})",
    )
    parser.add_argument(
        "--fresh-per-connection", action="store_true",
        help="give each client session a fresh cell (new sponge, sensor as at start); by "
        "default the cell remembers wear between sessions, as a real one does",
    )
    robots, sensors = kinds.known("robot"), kinds.known("sensor")
    parser.add_argument(
        "--robot", choices=[*robots, *ALIASES],
        help=f"one of {', '.join(robots)} (default: the config's [robot] kind)",
    )
    parser.add_argument(
        "--sensor", choices=sensors,
        help=f"one of {', '.join(sensors)} (default: the config's [sensor] kind)",
    )
    for name in robots:  # each kind's own route options (EGM: --egm-port)
        kinds.robot_kind(name).add_emulate_arguments(parser)
    for name in sensors:
        kinds.sensor_kind(name).add_emulate_arguments(parser)


def default_link_dir() -> Path:
    """Per-user folder of the stable symlinks (one running emulator per folder)."""
    return Path(tempfile.gettempdir()) / f"forcelearn-emulate-{os.getuid()}"


@contextmanager
def _stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """Set ``stop`` on SIGINT and SIGTERM (main thread only); restore the handlers after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in signals}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Serve the emulated cell until a signal (or ``stop``, for callers in-process)."""
    config = load_cell_config(args.config)
    stop = stop or threading.Event()
    robot = getattr(args, "robot", None) or config.robot_kind
    if robot in ALIASES:
        print(f"forcelearn emulate: --robot {robot} is deprecated; write --robot "
              f"{ALIASES[robot]}", file=sys.stderr)
        robot = ALIASES[robot]
    sensor = getattr(args, "sensor", None) or config.sensor_kind
    routes = {kind.name: route for kind in (kinds.robot_kind(robot), kinds.sensor_kind(sensor))
              if (route := kind.route_from_arguments(args)) is not None}
    cell = EmulatedCell(
        config, seed=args.seed, robot=robot, sensor=sensor, link_dir=args.link_dir,
        fresh_per_connection=args.fresh_per_connection, routes=routes,
    )
    sessions = ("a fresh cell per client session" if args.fresh_per_connection
                else "the cell remembers wear between client sessions")
    with _stop_on_signals(stop), cell:
        print(
            f"forcelearn emulate: emulated cell running, PID {os.getpid()} (seed {args.seed}, "
            f"{sessions}); Ctrl-C or `kill {os.getpid()}` stops it",
            flush=True,
        )
        for line in cell.describe():
            print(line)
        site = cell.site_config()
        if args.write_config is not None:
            atomic_write_bytes(args.write_config, site.encode())
            print(f"site config written to {args.write_config}")
        print("\n" + site, flush=True)
        while not stop.wait(WAIT_SLICE_S):
            pass
        print(f"forcelearn emulate: stopping: {cell.summary()}, {cell.sessions} client sessions",
              flush=True)
    return 0
