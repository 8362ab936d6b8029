"""Benchmark: what ``--live`` and a browser watching the page cost a run.

Runs the default §5 job as ``forcelearn run`` subprocesses, interleaved so a
change of the host's load falls on every mode alike: without ``--live``, with
``--live`` and no page open, and with ``--live`` and headless Chromium showing
the page for the whole run (on the same cores, the worst case: on site the
browser runs on another machine). It prints each run's wall time of the trials
(``summary.json`` ``wall_s``) and the median slowdown against the plain runs.
The figures depend on the host's load; run it on an idle machine.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from forcelearn.tools.live.browser import headless_page, require_browser

MODES = ("plain", "live", "browser")
_URL = re.compile(r"live page: (http://\S+)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench live``."""
    parser.add_argument("--trials", type=int, default=100, help="trials per run (default 100)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each mode (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="random seed")


def _run(mode: str, trials: int, seed: int, folder: Path) -> float:
    """One ``forcelearn run`` of ``mode``; its wall time of the trials, s."""
    out = folder / f"{mode}-{time.monotonic_ns()}"
    command = [sys.executable, "-m", "forcelearn.tools.cli", "run", "--no-progress",
               "--trials", str(trials), "--seed", str(seed), "--out", str(out)]
    if mode != "plain":
        command += ["--live", "--live-port", "0"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
    assert process.stderr is not None
    stderr_tail: list[str] = []
    url = None
    for line in process.stderr:
        stderr_tail = [*stderr_tail[-20:], line]
        match = _URL.search(line)
        if match:
            url = match.group(1)
            break
    rest = threading.Thread(target=lambda: stderr_tail.extend(process.stderr or []),
                            daemon=True)
    rest.start()
    try:
        if mode == "browser" and url is not None:
            with headless_page() as page:  # the page stays open, drawing, until the run ends
                page.goto(url)
                code = process.wait()
        else:
            code = process.wait()
    finally:
        if process.poll() is None:  # the browser failed: end the run it was to watch
            process.kill()
            process.wait()
    rest.join(5.0)
    if code != 0:
        raise RuntimeError(f"forcelearn run ({mode}) exited {code}: {''.join(stderr_tail)}")
    return float(json.loads((out / "summary.json").read_text())["wall_s"])


def run(args: argparse.Namespace) -> int:
    """Interleave the three modes ``--repeats`` times; print walls and slowdowns."""
    require_browser()
    walls: dict[str, list[float]] = {mode: [] for mode in MODES}
    with tempfile.TemporaryDirectory(prefix="forcelearn-bench-live-") as tmp:
        for repeat in range(args.repeats):
            for mode in MODES:
                wall = _run(mode, args.trials, args.seed, Path(tmp))
                walls[mode].append(wall)
                print(f"repeat {repeat + 1}, {mode:8s}: {args.trials} trials in {wall:.1f} s",
                      flush=True)
    plain = statistics.median(walls["plain"])
    for mode in MODES:
        median = statistics.median(walls[mode])
        print(f"{mode:8s}: median wall {median:.1f} s, {100 * (median / plain - 1):+.1f} % "
              "against plain")
    return 0
