"""The twin against hidden cells: writes docs/results/twin.md and its figure.

``python -m forcelearn.tools.results.twin --cells 30 --seed 1 --out DIR [--workers 2]``

1. draws the hidden cells (``forcelearn.tools.twin.hidden_cells``, generator ``--seed``);
2. per cell, as on site: ``forcelearn run --config cell-XX.toml --trials 60 --seed R``
   (probe + 60 trials), then ``forcelearn twin`` on that run directory alone; with
   ``--identify`` first ``forcelearn identify --seed R + IDENTIFY_SEED_OFFSET``. ``R`` is
   the cell's own (:func:`run_seed`), so each cell's sensor noise and zero walk are its own
   draws; ``--run-seed zero`` gives every cell seed 0 (and identify seed 0), as studies
   drawn before 2026-12-05 did: there every cell's sensor walked alike, scaled by its drift,
   and the study's pooled mean deviations measured that one walk;
3. per cell with a twin (``--learning-cells`` first cells; all by default): the learner over
   ``--seeds`` seeds on the twin.toml and on the hidden cell (seed 0 of the hidden cell is
   the site run itself); with ``--self-check EVERY``, every EVERY-th cell also runs the
   next ``--seeds`` seeds on the hidden cell: a perfect twin's agreement, the seeds'
   scatter alone;
4. compares (``twin_compare``) and writes ``DIR/twin.md`` and ``DIR/twin.png`` (``--page``
   and ``--figure`` to write them elsewhere, e.g. docs/results/).

Every command is a ``nice -n 10`` subprocess on a pool of ``--workers`` local processes; a
step whose ``.rc`` file exists is not run again, so a stopped study resumes where it
stopped, and ``--report-only`` only rewrites the page from what has finished.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from forcelearn.errors import StudyError
from forcelearn.tools.results import twin_calibration
from forcelearn.tools.results.twin_compare import (
    LearningSide,
    RunOutcome,
    TwinCheck,
    check_twin,
    learning_side,
    run_outcome,
)
from forcelearn.tools.results.twin_identified import page_lines
from forcelearn.tools.results.twin_page import CellResult, write_figure, write_page

TRIALS = 60
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""Each step's BLAS on one thread: the study runs one process per worker, and the twin's
matrices are small (bursts x parameters); BLAS threads waiting on a shared machine cost a
cell's fit 3x its CPU (a 1717 x 11 SVD 0.2 s instead of 0.5 ms), same results."""


def _step(rc_file: Path, command: list[str], log: Path) -> int:
    """Run ``command`` niced unless ``rc_file`` exists; its exit code (kept in ``rc_file``)."""
    if rc_file.exists():
        return int(rc_file.read_text().strip() or "1")
    log.parent.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    with log.open("w") as out:
        rc = subprocess.run(["nice", "-n", "10", *command], stdout=out,
                            stderr=subprocess.STDOUT, check=False,
                            env={**os.environ, **ONE_THREAD}).returncode
    print(f"{log.parent.name}: {log.stem} rc {rc} in {time.monotonic() - started:.0f} s",
          flush=True)
    rc_file.write_text(f"{rc}\n")
    return rc


def _forcelearn(*args: str) -> list[str]:
    return [sys.executable, "-m", "forcelearn.tools.cli", *args]


IDENTIFY_SEED_OFFSET = 100_000
"""A cell's identification seed over its run seed (run seeds stay under it for generator
seeds under 100)."""


def run_seed(generator_seed: int, cell: str) -> int:
    """The site run's seed of ``cell`` (``cell-XX``) in the study of ``generator_seed``."""
    return 1000 * generator_seed + int(cell.removeprefix("cell-"))


def site_and_twin(out: Path, cell: str, identify: bool = False, fit: bool = True,
                  refit: bool = False, seed: int = 0) -> None:
    """The site run (``seed``), with ``identify`` an identification run, then the twin.

    The twin is fitted on that run alone (and the identification's records); skips
    finished steps. ``fit`` False: the cell's runs only. ``refit``: fit the twin again
    even when a fit finished (the fit's code changed, the runs did not). The
    identification's seed is ``seed + IDENTIFY_SEED_OFFSET`` (0 with ``seed`` 0).
    """
    folder = out / cell
    folder.mkdir(parents=True, exist_ok=True)
    site = folder / "site"
    config = str(out / "cells" / f"{cell}.toml")
    if not (folder / "site.done").exists() and site.exists():
        _remove(site)
    _step(folder / "site.done",
          _forcelearn("run", "--config", config, "--trials", str(TRIALS), "--seed", str(seed),
                      "--out", str(site), "--no-progress"),
          folder / "site.log")
    extra: list[str] = []
    identify_seed = seed + IDENTIFY_SEED_OFFSET if seed else 0
    if identify and identification(out, cell, identify_seed) == 0:  # failed: the run alone
        extra = ["--identification", str(folder / "identify")]
    if not fit:
        return
    (folder / "twin").mkdir(exist_ok=True)
    if refit and (folder / "twin.done").exists():
        (folder / "twin.done").unlink()
    _step(folder / "twin.done",
          _forcelearn("twin", str(site), *extra, "--out", str(folder / "twin" / "twin.toml"),
                      "--no-figure"),
          folder / "twin.log")
    print(f"{cell}: twin {(folder / 'twin.done').read_text().strip()}", flush=True)


def identification(out: Path, cell: str, seed: int = 0) -> int:
    """The cell's ``forcelearn identify`` run with ``seed`` (skipped when done); its exit code."""
    folder = out / cell
    folder.mkdir(parents=True, exist_ok=True)
    rc = _step(folder / "identify.done",
               _forcelearn("identify", "--config", str(out / "cells" / f"{cell}.toml"),
                           "--seed", str(seed), "--out", str(folder / "identify")),
               folder / "identify.log")
    print(f"{cell}: identification {rc}", flush=True)
    return rc


def learning_run(out: Path, cell: str, side: str, seed: int) -> None:
    """One learning run of ``cell`` on ``side`` (``hidden`` or ``twin``) with ``seed``."""
    folder = out / cell / "learn"
    folder.mkdir(parents=True, exist_ok=True)
    config = (out / "cells" / f"{cell}.toml" if side == "hidden"
              else out / cell / "twin" / "twin.toml")
    run = folder / f"{side}-s{seed}"
    if not (folder / f"{side}-s{seed}.done").exists() and run.exists():
        _remove(run)
    _step(folder / f"{side}-s{seed}.done",
          _forcelearn("run", "--config", str(config), "--trials", str(TRIALS), "--seed",
                      str(seed), "--out", str(run), "--no-progress"),
          folder / f"{side}-s{seed}.log")


def _remove(path: Path) -> None:
    """Remove a run directory a stopped study left half-written."""
    shutil.rmtree(path)


def _run_dir(out: Path, cell: str, side: str, seed: int) -> Path | None:
    """A finished run directory of the learning part, or None."""
    if side == "hidden" and seed == 0:
        rc, run = out / cell / "site.done", out / cell / "site"
    else:
        rc = out / cell / "learn" / f"{side}-s{seed}.done"
        run = out / cell / "learn" / f"{side}-s{seed}"
    if rc.exists() and rc.read_text().strip() == "0":
        return run
    return None


def _side(out: Path, cell: str, side: str, seeds: int, first: int = 0) -> LearningSide | None:
    if seeds == 0:
        return None
    outcomes: list[RunOutcome] = []
    for seed in range(first, first + seeds):
        run = _run_dir(out, cell, side, seed)
        if run is None:
            return None
        outcomes.append(run_outcome(run))
    return learning_side(outcomes, TRIALS)


def collect(out: Path, cells: Sequence[str], seeds: int) -> list[CellResult]:
    """Every cell's result from what has finished."""
    results = []
    for cell in cells:
        twin_json = out / cell / "twin" / "twin.json"
        site_rc = out / cell / "site.done"
        check: TwinCheck | None = None
        if twin_json.exists():
            check = check_twin(cell, out / "cells" / f"{cell}.truth.json", twin_json)
        results.append(CellResult(
            cell=cell, truth_path=out / "cells" / f"{cell}.truth.json",
            site_rc=int(site_rc.read_text()) if site_rc.exists() else None, check=check,
            hidden=_side(out, cell, "hidden", seeds), twin=_side(out, cell, "twin", seeds),
            hidden_again=_side(out, cell, "hidden", seeds, first=seeds)))
    return results


def main(argv: Sequence[str] | None = None) -> int:
    """Run (or resume) the study and write the page."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=30, help="hidden cells (default 30)")
    parser.add_argument("--seed", type=int, default=1, help="generator seed (default 1)")
    parser.add_argument("--out", type=Path, required=True, help="study folder")
    parser.add_argument("--workers", type=int, default=2, help="local processes (default 2)")
    parser.add_argument("--seeds", type=int, default=5,
                        help="learner seeds (default 5; 0: no learning part)")
    parser.add_argument("--identify", action="store_true",
                        help="also run forcelearn identify on each cell; its twin uses it")
    parser.add_argument("--identify-first", action="store_true",
                        help="with --identify: every cell's identification before any site run")
    parser.add_argument("--runs-only", action="store_true",
                        help="run the cells' site (and identification) runs, fit nothing")
    parser.add_argument("--run-seed", choices=("cell", "zero"), default="cell",
                        help="the cells' site and identification run seeds: each cell its own "
                             "(default), or 0 for every cell (studies drawn before 2026-12-05)")
    parser.add_argument("--refit", action="store_true",
                        help="fit every twin again (the fit changed, the runs did not)")
    parser.add_argument("--learning-cells", type=int, default=None,
                        help="run the learning part on the first N cells with a twin only")
    parser.add_argument("--self-check", type=int, default=0, metavar="EVERY",
                        help="also run the hidden cell with the next --seeds seeds on every "
                             "EVERY-th cell: how well a perfect twin could agree (0: off)")
    parser.add_argument("--shaped", type=float, default=0.0, metavar="SHARE",
                        help="share of the drawn cells whose strip has periodic shapes of its "
                             "own (hidden_cells --shaped; default 0)")
    parser.add_argument("--report-only", action="store_true",
                        help="run nothing; write the page from what has finished")
    parser.add_argument("--page", type=Path, default=None, help="page (default OUT/twin.md)")
    parser.add_argument("--figure", type=Path, default=None,
                        help="figure (default OUT/twin.png)")
    args = parser.parse_args(argv)
    if args.cells < 1 or args.workers < 1 or args.seeds < 0:
        parser.error("--cells and --workers must be at least 1, --seeds at least 0")
    out: Path = args.out
    cells = [f"cell-{i:02d}" for i in range(1, args.cells + 1)]
    if not args.report_only:
        if not all((out / "cells" / f"{c}.toml").exists() for c in cells):
            subprocess.run([sys.executable, "-m", "forcelearn.tools.twin.hidden_cells",
                            "--count", str(args.cells), "--seed", str(args.seed),
                            "--out", str(out / "cells"), "--shaped", str(args.shaped)],
                           check=True)
        seeds = {c: run_seed(args.seed, c) if args.run_seed == "cell" else 0 for c in cells}
        if args.identify and args.identify_first:  # the arm of every cell before site runs
            with ThreadPoolExecutor(args.workers) as pool:
                list(pool.map(lambda c: identification(
                    out, c, seeds[c] + IDENTIFY_SEED_OFFSET if seeds[c] else 0), cells))
        with ThreadPoolExecutor(args.workers) as pool:
            list(pool.map(lambda c: site_and_twin(out, c, args.identify, not args.runs_only,
                                                  args.refit, seeds[c]), cells))
        if args.runs_only:
            print(f"ran the cells' runs in {out}; fit them without --runs-only")
            return 0
        with_twin = [c for c in cells if (out / c / "twin" / "twin.toml").exists()]
        chosen = with_twin[: args.learning_cells] if args.learning_cells else with_twin
        jobs = [(c, side, seed) for c in chosen for seed in range(args.seeds)
                for side in ("twin", "hidden") if not (side == "hidden" and seed == 0)]
        if args.self_check > 0:
            jobs += [(c, "hidden", seed) for c in cells[args.self_check - 1::args.self_check]
                     for seed in range(args.seeds, 2 * args.seeds)]
        with ThreadPoolExecutor(args.workers) as pool:
            list(pool.map(lambda job: learning_run(out, *job), jobs))
    try:
        results = collect(out, cells, args.seeds)
    except StudyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    figure = args.figure or out / "twin.png"
    write_figure(results, figure)
    page = args.page or out / "twin.md"
    write_page(results, page, figure, generator_seed=args.seed, seeds=args.seeds,
               trials=TRIALS, workers=args.workers, identify=args.identify,
               run_seed=args.run_seed, shaped=args.shaped)
    try:
        checks = page_lines(out, cells) + twin_calibration.page_lines(out, cells)
    except StudyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    page.write_text(page.read_text() + "\n" + "\n".join(checks))
    print(f"wrote {page} and {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
