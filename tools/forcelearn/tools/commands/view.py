"""``forcelearn view RUN_DIR``: the live page of a finished run, or of one in progress.

A run directory with ``live.ndjson`` (every ``forcelearn run`` writes it) is
replayed, then followed as another process appends to it. Older run
directories and contour simulations are shown from trials.csv, summary.json
and the steps_*.csv logs. The page is read-only; Ctrl-C stops serving.
"""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path

from forcelearn.tools.live.journal import (
    JOURNAL,
    JournalFollower,
    load_run_directory,
    read_meta,
)
from forcelearn.tools.live.model import LiveModel
from forcelearn.tools.live.server import LOOPBACK
from forcelearn.tools.live.session import DEFAULT_PORT, start_server


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn view``."""
    parser.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run directory")
    parser.add_argument(
        "--port",
        type=int,
        default=DEFAULT_PORT,
        metavar="N",
        help=f"port of the page (default {DEFAULT_PORT}; 0: any free port)",
    )
    parser.add_argument(
        "--bind",
        default=LOOPBACK,
        metavar="ADDR",
        help="address to serve the page on (default 127.0.0.1; others print a warning)",
    )


def open_model(folder: Path) -> tuple[LiveModel, JournalFollower | None]:
    """The model of a run directory, and the follower keeping it up to date (if any)."""
    journal = folder / JOURNAL
    meta = read_meta(journal) if journal.exists() else None
    if meta is not None:
        model = LiveModel(meta.__class__(**{**meta.__dict__, "source": "view"}))
        follower = JournalFollower(journal, model)
        follower.start()
        return model, follower
    if (folder / "summary.json").exists() and (folder / "trials.csv").exists():
        return load_run_directory(folder), None
    raise FileNotFoundError(
        f"{folder} holds no {JOURNAL} and no finished run (summary.json, trials.csv)"
    )


def run(args: argparse.Namespace) -> int:
    """Serve the page of RUN_DIR until Ctrl-C."""
    try:
        model, follower = open_model(args.run_dir)
    except (FileNotFoundError, NotADirectoryError) as exc:
        print(f"forcelearn view: {exc}", file=sys.stderr)
        return 2
    server = start_server(model, args.bind, args.port, "page of the run")
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        return 0
    finally:
        server.close()
        if follower is not None:
            follower.close()
    return 0
