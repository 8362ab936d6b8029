"""The commands' side: ``--live`` options, and a run wrapped with its journal and live page."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from forcelearn.errors import ConfigError
from forcelearn.tools.live.journal import JOURNAL, JournalFollower, JournalWriter
from forcelearn.tools.live.model import LiveMeta, LiveModel
from forcelearn.tools.live.publish import LivePublisher, RowExtras, describe_error
from forcelearn.tools.live.server import LOOPBACK, LiveServer, bind_warning

DEFAULT_PORT = 8750


def add_live_arguments(parser: argparse.ArgumentParser, journal: bool = True) -> None:
    """``--live``, ``--live-port``, ``--live-bind``."""
    parser.add_argument(
        "--live",
        action="store_true",
        help="serve a read-only live page of the run on 127.0.0.1 (docs/live.md)",
    )
    parser.add_argument(
        "--live-port",
        type=int,
        default=DEFAULT_PORT,
        metavar="N",
        help=f"port of the live page (default {DEFAULT_PORT}; 0: any free port)",
    )
    parser.add_argument(
        "--live-bind",
        default=LOOPBACK,
        metavar="ADDR",
        help="address to serve the page on (default 127.0.0.1; others print a warning)",
    )


def start_server(model: LiveModel, host: str, port: int, what: str) -> LiveServer:
    """Serve the page; print its URL (and a warning off loopback) on stderr."""
    warning = bind_warning(host)
    if warning:
        print(warning, file=sys.stderr)
    try:
        server = LiveServer(model, host, port)
    except OSError as exc:
        raise ConfigError(
            f"cannot serve the live page on {host}:{port} ({exc.strerror or exc}); "
            "choose another port with --live-port N (0: any free port)"
        ) from exc
    print(f"{what}: {server.url} (read-only)", file=sys.stderr, flush=True)
    return server


@contextmanager
def live_run(
    meta: LiveMeta,
    args: argparse.Namespace,
    journal_dir: Path | None,
    extras: RowExtras | None = None,
) -> Iterator[LivePublisher]:
    """A publisher for the run: a journal in ``journal_dir``, a live page with ``--live``.

    The run's outcome is published (finished, or the error that stopped it);
    the page closes when the run ends.
    """
    model = LiveModel(meta) if args.live else None
    journal = None
    if journal_dir is not None:
        path = journal_dir / JOURNAL
        if model is not None and path.exists():  # a resumed run: show what came before
            JournalFollower(path, model).read_available()
        journal = JournalWriter(path)
    server = start_server(model, args.live_bind, args.live_port, "live page") if model else None
    publisher = LivePublisher(meta, model, journal, extras)
    try:
        yield publisher
    except BaseException as exc:
        kind, message = describe_error(exc)
        publisher.event(kind, message)
        publisher.finish(error=f"{kind}: {message}")
        raise
    else:
        publisher.finish()
    finally:
        if server is not None:
            server.close()
