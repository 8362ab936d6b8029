r"""Paper §5 over seeds on a cell given by a config file (e.g. the EGM or Net F/T cell).

``forcelearn study surface`` sweeps ``--set`` keys of the built-in emulated
cell; a device *kind* (``[robot] kind``, ``[sensor] kind``) changes the
config's types, not a value, so this module runs the same study runner over
a config file instead: one whole ``forcelearn run --config FILE --seed S``
per seed, resumable in ``--study-dir``, and writes a Markdown report.

Usage::

    python -m forcelearn.tools.results.surface_kind --config examples/egm-cell.toml \\
        --name egm --seeds 10 --trials 300 --out docs/results/surface-egm.md
"""

from __future__ import annotations

import argparse
import functools
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from forcelearn.run_output import median_range
from forcelearn.site.config import load_cell_config
from forcelearn.tools.study.grid import RunSpec, result_row
from forcelearn.tools.study.runner import run_study
from forcelearn.tools.study.tasks import StudyTask

PAPER_REPETITIONS = 237
"""Trials the paper's §5 cell needed (the target to meet or beat)."""


def run_config_chunk(config_path: str, specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Run each spec as ``forcelearn run --config config_path`` in a scratch folder."""
    from forcelearn.tools.experiments.surface_run import execute
    from forcelearn.tools.experiments.surface_state import prepare_run

    rows = []
    for spec in specs:
        with tempfile.TemporaryDirectory(prefix="forcelearn-study-") as folder:
            run, _ = prepare_run(
                Path(config_path), Path(folder) / "run", spec.trials, spec.seed, resume=False
            )
            summary = execute(run, None)
        rows.append(result_row(spec, run.config, summary))
    return rows


def _own_chunk(spec: RunSpec) -> str:
    return spec.run_id


def config_task(name: str, config_path: Path) -> StudyTask:
    """A study task whose runs are whole runs of ``config_path`` (one run per chunk)."""
    path = str(config_path.resolve())
    return StudyTask(
        f"surface-{name}",
        f"paper §5 on the cell of {config_path}",
        functools.partial(load_cell_config, path),
        functools.partial(run_config_chunk, path),
        _own_chunk,
        batched=False,
    )


def report(name: str, command: str, rows: list[dict[str, Any]], trials: int, wall_s: float,
           config_path: Path) -> str:
    """The Markdown page of one study."""
    config = load_cell_config(config_path)

    def never_as_budget(key: str) -> list[float]:
        return [trials if r.get(key) in (None, "") else float(r[key]) for r in rows]

    converged = [r for r in rows if r.get("converged_trial") not in (None, "")]
    lines = [
        f"# Force tracking on the sponge (paper §5), emulated {name} cell",
        "",
        f"Made by `{command}` ({wall_s:.0f} s of wall time on the shared 2-core machine).",
        "",
        f"Cell: `{config_path}`: robot `{config.robot_kind}`, sensor `{config.sensor_kind}`, "
        "both emulated and reached through their real drivers (the in-process routes of "
        "the built-in cell, docs/emulators.md; the Net F/T box over loopback).",
        "Converged: 10 complete trials in a row, each with force RMS ≤ 5 % of the desired",
        "force; a seed that never converges counts as the budget. Trials count from 0.",
        "",
        "| figure | median (range) |",
        "|---|---|",
        f"| seeds converged | {len(converged)} / {len(rows)} |",
        f"| trials to converge (target ≤ {PAPER_REPETITIONS}) | "
        f"{median_range(never_as_budget('converged_trial'), '{:.0f}')} |",
        f"| trials to the global criterion | "
        f"{median_range(never_as_budget('criterion_trial'), '{:.0f}')} |",
        f"| final force RMS, median of the last 50 trials (N) | "
        f"{median_range([float(r['final_force_rms_n']) for r in rows], '{:.3f}')} |",
        f"| failed trials | {median_range([float(r['failures']) for r in rows], '{:.0f}')} |",
        f"| cell time per run (s, simulated) | "
        f"{median_range([float(r['cell_time_s']) for r in rows], '{:.0f}')} |",
        f"| wall time per run (s) | "
        f"{median_range([float(r['wall_s']) for r in rows], '{:.1f}')} |",
        "",
        "| seed | converged trial | criterion trial | final force RMS (N) | failures | "
        "cell time (s) |",
        "|---|---|---|---|---|---|",
    ]
    for r in sorted(rows, key=lambda r: int(r["seed"])):
        lines.append(
            f"| {r['seed']} | {r.get('converged_trial') or 'never'} | "
            f"{r.get('criterion_trial') or 'never'} | {float(r['final_force_rms_n']):.3f} | "
            f"{r['failures']} | {float(r['cell_time_s']):.0f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the seeds over the config's cell and write the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, required=True)
    parser.add_argument("--name", required=True, help="label of the cell, e.g. egm or netft")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--trials", type=int, default=300)
    parser.add_argument("--workers", type=int, help="local processes (default: all cores)")
    parser.add_argument("--out", type=Path, help="report (default docs/results/surface-NAME.md)")
    parser.add_argument("--study-dir", type=Path, help="default runs/study-surface-NAME")
    args = parser.parse_args(argv)
    out = args.out or Path(f"docs/results/surface-{args.name}.md")
    study_dir = args.study_dir or Path(f"runs/study-surface-{args.name}")
    command = (
        f"python -m forcelearn.tools.results.surface_kind --config {args.config} --name {args.name}"
        f" --seeds {args.seeds} --trials {args.trials}"
    )
    started = time.perf_counter()
    outcome = run_study(
        config_task(args.name, args.config),
        study_dir,
        args.trials,
        range(args.seeds),
        [{}],
        workers=args.workers,
        command=command,
        progress=False,
    )
    wall = time.perf_counter() - started
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(report(args.name, command, outcome.rows, args.trials, wall, args.config))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
