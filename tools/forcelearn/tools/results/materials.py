"""The main job on real foam (the materials study): writes docs/results/materials.md and its figure.

``python -m forcelearn.tools.results.materials --cells 30 --seed 37 --out DIR [--workers 2]``

1. draws the hidden cells (``forcelearn.tools.twin.hidden_cells``, generator ``--seed``);
2. per cell, ``forcelearn run --config cell-XX.toml --trials 100 --seed 0`` (ended 10 trials
   after it converged, ``[run] stop_after_converged``) with each start
   (``[run] learner_start`` "probe", the default, and "cold") and the default
   ``[task] approach`` ("auto": from the loading side where the probe resolves hysteresis);
3. per hysteretic cell (the truth's h > 0), the same run with each of ``--designs``
   (``[task] approach`` values: "direction", the last move's direction as a second BOXES
   input; "direct", the main job before this study, moving straight to each step), so the
   designs compare on the same cells and seeds;
   the runs go in the order of :func:`plan`, so a study stopped early has the default
   start on every cell first;
4. writes ``DIR/materials.md`` (the table) and ``DIR/materials.png`` (force RMS against
   trial, in bands, of the hysteretic cells with each approach); ``--page`` and
   ``--figure`` to write them elsewhere (docs/results/).

Every run is a ``nice -n 10`` subprocess on a pool of ``--workers`` local processes; a run
whose ``.rc`` file exists is not run again, so a stopped study resumes, and
``--report-only`` only rewrites the page from what has finished; ``--only cell-18 ...``
runs those cells only (a re-run after a fix: delete their run folders and ``.rc`` files),
``--variants probe-auto ...`` those starts and approaches only (a budget's order).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tomllib
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import tomli_w

from forcelearn.tools.results.materials_page import (
    STIFF_N_PER_MM,
    CellRun,
    read_run,
    write_figure,
    write_page,
)
from forcelearn.tools.twin.hidden_cells import write_hidden_cells

TRIALS = 100
STOP_AFTER_CONVERGED = 10
"""A run ends this many trials after it converged (its last 10 trials then say whether it
ended in band): the study's cost goes to the cells that do not converge."""
STARTS = ("probe", "cold")


@dataclass(frozen=True)
class Job:
    """One run of the study: a cell, a learner start and a task approach."""

    cell: str
    start: str
    approach: str
    config: Path
    out: Path

    def command(self, trials: int, seed: int) -> list[str]:
        """The ``forcelearn run`` command of this job."""
        return [sys.executable, "-m", "forcelearn.tools.cli", "run", "--config", str(self.config),
                "--trials", str(trials), "--seed", str(seed), "--out", str(self.out),
                "--no-progress"]


def variant_config(cell_config: Path, start: str, approach: str, out: Path) -> Path:
    """Write the cell's config with ``[run] learner_start`` and ``[task] approach`` set."""
    data: dict[str, Any] = tomllib.loads(cell_config.read_text(encoding="utf-8"))
    data.setdefault("run", {})["learner_start"] = start
    data["run"]["stop_after_converged"] = STOP_AFTER_CONVERGED
    data.setdefault("task", {})["approach"] = approach
    if approach == "direction":  # a second input: its extent 0 (a direction learns alone)
        learner = data.setdefault("learner", {})
        learner["extent"] = [*learner.get("extent", [3])[:1], 0]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(tomli_w.dumps(data), encoding="utf-8")
    return out


def plan(cells_dir: Path, runs_dir: Path, designs: Sequence[str]) -> list[Job]:
    """Every job of the study, in waves a study stopped early still reports.

    1. every cell with the default start and approach;
    2. each hysteretic cell (truth h > 0) with the first of ``designs``, default
       start; then with the next design, and so on (the designs compared on the
       same cells, and the before of the figure);
    3. the cold start on the hysteretic and the stiff cells (where the approach
       and the probe's density matter);
    4. the cold start on the other cells.
    """
    waves: list[list[Job]] = [[] for _ in range(len(designs) + 3)]
    cold_first, cold_rest = len(designs) + 1, len(designs) + 2
    for config in sorted(cells_dir.glob("cell-*.toml")):
        name = config.stem
        truth = json.loads((cells_dir / f"{name}.truth.json").read_text(encoding="utf-8"))
        sponge = truth["sponge"]
        hysteretic = sponge["hysteresis_loss"] > 0
        stiff = sponge["stiffness_n_per_mm"] >= STIFF_N_PER_MM
        variants = [(0, "probe", "auto"),
                    (cold_first if hysteretic or stiff else cold_rest, "cold", "auto")]
        if hysteretic:
            variants += [(1 + i, "probe", design) for i, design in enumerate(designs)]
        for wave, start, approach in variants:
            path = variant_config(config, start, approach,
                                  runs_dir / "configs" / f"{name}-{start}-{approach}.toml")
            waves[wave].append(Job(name, start, approach, path,
                                   runs_dir / f"{name}-{start}-{approach}"))
    return [job for wave in waves for job in wave]


def run_job(job: Job, trials: int, seed: int) -> int:
    """Run ``job`` niced unless its ``.rc`` file exists; its exit code."""
    rc_file = job.out.with_suffix(".rc")
    if rc_file.exists():
        return int(rc_file.read_text().strip() or "1")
    if (job.out / "summary.json").exists():  # finished by a study that was stopped
        rc_file.write_text("0\n")
        return 0
    with job.out.with_suffix(".log").open("w") as log:
        rc = subprocess.run(["nice", "-n", "10", *job.command(trials, seed)], stdout=log,
                            stderr=subprocess.STDOUT, check=False).returncode
    rc_file.write_text(f"{rc}\n")
    print(f"{job.out.name}: exit {rc}", flush=True)
    return rc


def collect(jobs: Sequence[Job], cells_dir: Path) -> list[CellRun]:
    """The finished runs of ``jobs`` with their cells' truth."""
    runs = []
    for job in jobs:
        if (job.out / "summary.json").exists():
            truth = json.loads((cells_dir / f"{job.cell}.truth.json").read_text(encoding="utf-8"))
            runs.append(read_run(job.out, job.cell, job.start, job.approach, truth))
    return runs


def main(argv: Sequence[str] | None = None) -> int:
    """Run the study (module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.results.materials",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--cells", type=int, default=30, help="hidden cells (default 30)")
    parser.add_argument("--seed", type=int, default=37, help="generator seed (default 37)")
    parser.add_argument("--run-seed", type=int, default=0, help="the runs' seed (default 0)")
    parser.add_argument("--trials", type=int, default=TRIALS, help=f"default {TRIALS}")
    parser.add_argument("--designs", nargs="*", default=["direction", "direct"],
                        help="task.approach values compared on the hysteretic cells")
    parser.add_argument("--workers", type=int, default=1, help="runs at once (default 1)")
    parser.add_argument("--out", type=Path, required=True, help="the study's folder")
    parser.add_argument("--page", type=Path, help="write the page here (default DIR/materials.md)")
    parser.add_argument("--figure", type=Path, help="the figure (default DIR/materials.png)")
    parser.add_argument("--report-only", action="store_true", help="only rewrite the page")
    parser.add_argument("--only", nargs="*", default=None, metavar="CELL",
                        help="run only these cells (e.g. cell-18); the page has every finished run")
    parser.add_argument("--variants", nargs="*", default=None, metavar="START-APPROACH",
                        help="run only these variants (e.g. probe-auto cold-auto probe-direction)")
    args = parser.parse_args(argv)
    cells_dir, runs_dir = args.out / "cells", args.out / "runs"
    if not (cells_dir / "hidden-cells.json").exists():
        write_hidden_cells(args.cells, args.seed, cells_dir)
    jobs = plan(cells_dir, runs_dir, args.designs)
    if not args.report_only:
        todo = [job for job in jobs if (args.only is None or job.cell in args.only) and (
            args.variants is None or f"{job.start}-{job.approach}" in args.variants)]
        with ThreadPoolExecutor(max_workers=max(1, args.workers)) as pool:
            list(pool.map(lambda job: run_job(job, args.trials, args.run_seed), todo))
    runs = collect(jobs, cells_dir)
    figure = args.figure or args.out / "materials.png"
    page = args.page or args.out / "materials.md"
    write_figure(runs, figure)
    command = ["python -m forcelearn.tools.results.materials",
               *(a for a in sys.argv[1:] if a != "--report-only")]  # the study's own command
    write_page(runs, page, figure, args.seed, args.trials, " ".join(command))
    print(f"{len(runs)} of {len(jobs)} runs: {page}, {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
