"""The live page of a run directory, screenshot in headless Chromium (a figure for the docs).

``python -m forcelearn.tools.live.screenshot RUN_DIR --out PNG [--at-trial N]``
loads the run into the live page's model, serves it with the live server on
127.0.0.1 (a free port), opens it with Playwright in the system Chromium, waits
until the page has drawn it and saves a full-page PNG (how the README's
``docs/results/live_run.png`` is made; needs ``pip install 'forcelearn[browser]'``
and a ``chromium``).

With ``--at-trial N`` the run's journal (``live.ndjson``) is replayed up to the
moment trial N (as the page counts, from 1) had drawn its last step: the page its
``--live`` viewer saw then, from the same published data, except "updates folded"
(which counts frames a live viewer skipped, 0 here). Without it, the whole run, as
``forcelearn view RUN_DIR`` shows it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from forcelearn.tools.live.browser import headless_page, wait_rendered
from forcelearn.tools.live.journal import (
    JOURNAL,
    JournalFollower,
    load_run_directory,
    read_meta,
    replay_until_trial,
)
from forcelearn.tools.live.model import LiveModel
from forcelearn.tools.live.server import LOOPBACK, LiveServer

PLOTS = {"surface": 4, "contour": 2}
"""Plots the page draws for each task."""


def load_model(run_dir: Path, at_trial: int | None) -> LiveModel:
    """The page's model of ``run_dir``: the whole run, or as it was during trial ``at_trial``.

    Raises:
        ValueError: ``at_trial`` is below 1, the run has no journal, or its journal
            ends before that trial's record.
        FileNotFoundError: ``run_dir`` holds no run.
    """
    if at_trial is not None and at_trial < 1:
        raise ValueError(f"--at-trial {at_trial}: trials count from 1")
    journal = run_dir / JOURNAL
    meta = read_meta(journal) if journal.exists() else None
    if meta is None:
        if at_trial is not None:
            raise ValueError(f"--at-trial needs the run's journal; {journal} is missing or empty")
        return load_run_directory(run_dir)
    if at_trial is None:  # the run as far as it got, as `forcelearn view` shows it
        model = LiveModel(dataclasses.replace(meta, source="view"))
        JournalFollower(journal, model).read_available()
    else:
        model = LiveModel(meta)
        replay_until_trial(journal, model, at_trial - 1)
    return model


def screenshot(model: LiveModel, out: Path, width: int, height: int) -> dict[str, object]:
    """Serve ``model``'s page on loopback, save its screenshot as ``out``; what the page shows."""
    expected = int(model.snapshot()["status"]["trial"])
    out.parent.mkdir(parents=True, exist_ok=True)
    with LiveServer(model, LOOPBACK, 0) as server, headless_page(width, height) as page:
        page.goto(server.url)
        seen = wait_rendered(page, PLOTS.get(model.meta.task, 4), after_trial=expected - 1)
        page.screenshot(path=out, full_page=True)
    return seen


def main(argv: list[str] | None = None) -> int:
    """Screenshot the live page of RUN_DIR; print what the page shows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run directory")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    parser.add_argument(
        "--at-trial",
        type=int,
        metavar="N",
        help="the page during trial N (from 1), replayed from live.ndjson (default: the end)",
    )
    parser.add_argument("--width", type=int, default=1400, help="viewport width, px")
    parser.add_argument(
        "--height", type=int, default=720, help="viewport height, px (the PNG grows to the page)"
    )
    args = parser.parse_args(argv)
    try:
        model = load_model(args.run_dir, args.at_trial)
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    seen = screenshot(model, args.out, args.width, args.height)
    print(json.dumps(seen))
    print(f"figure: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
