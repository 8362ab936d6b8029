"""``forcelearn bench all``: every speed figure beside its floor, measured in the same run.

A shared or slow machine makes every figure slower; the floors
(:mod:`~forcelearn.tools.benchmarks.floors`: pty echo, python-can virtual bus
round trip, numpy foam-law step) are measured in the same process, at the
start and again just before each figure (a shared machine's load changes
within minutes), and each figure is printed as a ratio to the floor measured
just before it, so a reader can compare a figure across machines
(docs/performance.md keeps the table). The emulated cells are compared with
the link + JR3 cell of the same run:

=========================  ======================  ===============================
figure                     ratio                   target (docs/performance.md)
=========================  ======================  ===============================
link move round trip p50   / (2 x pty echo)        <= 1.3
 ... and its protocol      / the bare exchange     - (protocol_floors: the move's own
 floor                                             writes and reads, no protocol work)
JR3 single read            reads/s / CAN trips/s   >= 0.9
 ... and its protocol      / bare exchanges/s      - (SYNC out, two frames back; its
 floor                                             ratio to the CAN trips caps the read's)
Surface-v0 step            step time / pty echo    500 steps/s where the echo is 255 us
SurfaceVec-v0, N = 64      env steps per foam      100,000 steps/s on one core
                           step (x foam step s)
cells: real-time factor    EGM, Net F/T, EGM +     >= 1 / 1.5 (within 1.5x)
 (wall and CPU)            Net F/T / link + JR3
cells: steps per CPU s     / link + JR3's          >= 1 / 1.5
learner / contour, N = 64  steps x foam step s     100,000 steps/s on one core
=========================  ======================  ===============================

A cell's real-time factor is the trials' cell time over the time from the
start of ``forcelearn run``'s code path to the last trial's end (the probe
included, as in summary.json), in wall time and in the process's CPU time; a
shared machine disturbs the CPU figure far less. The trials are the same on
every cell (4 trials of 20 steps after a probe), so steps per CPU second
compare the cells' cost for the same work, whatever cell time their robots
take (an EGM step takes about half a computer-link step's cell time, which
halves its real-time factor for the same CPU). Both are also given for the
trials after the first alone (no probe, no first-use imports, which the
first cell timed pays): what each further trial of a long run costs.

The 1-minute load average is printed with every figure. ``--quick`` shortens
every figure (a smoke run: the ratios are noisier). Results go to stdout as a
Markdown table; ``--json PATH`` also writes them.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.tools.benchmarks import floors as floor_module

CELL_CONFIGS: dict[str, str | None] = {
    "link + JR3": None,
    "EGM + JR3": "examples/egm-cell.toml",
    "link + Net F/T": "examples/netft-cell.toml",
    "EGM + Net F/T": "examples/egm-netft-cell.toml",
}
"""The emulated cells timed, by label: their config TOML (None: the default cell)."""


@dataclass(frozen=True)
class Figure:
    """One speed figure and its ratio to a floor of the same run."""

    name: str
    value: float
    unit: str
    ratio: float
    ratio_means: str
    target: str
    floor: str
    """The floor this figure's ratio used, as measured just before it."""
    load: float = 0.0
    """The host's 1-minute load average when the figure was measured."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench all``."""
    parser.add_argument("--quick", action="store_true", help="short runs (noisier ratios)")
    parser.add_argument("--trials", type=int, default=4, help="trials per emulated cell")
    parser.add_argument("--seconds", type=float, default=10.0, help="Surface-v0 wall time (s)")
    parser.add_argument("--examples", type=Path, default=Path("examples"),
                        help="folder of the example cell TOMLs (default ./examples)")
    parser.add_argument("--skip", nargs="*", default=[],
                        choices=["link", "jr3", "env", "vec", "cells", "learner", "contour"],
                        help="figures not to measure")
    parser.add_argument("--json", type=Path, help="also write the floors and figures here")


def _load() -> float:
    """The 1-minute load average (0.0 where the platform has none)."""
    try:
        return os.getloadavg()[0]
    except OSError:
        return 0.0


def _timed(label: str, fn: Callable[[], Figure | list[Figure]]) -> list[Figure]:
    started = time.perf_counter()
    result = fn()
    load = _load()
    figures = [replace(f, load=load) for f in (result if isinstance(result, list) else [result])]
    print(f"  {label}: {time.perf_counter() - started:.1f} s, load {load:.2f}", flush=True)
    return figures


def _echo() -> tuple[float, str]:
    echo = floor_module.pty_echo_s()
    return echo, f"pty echo {echo * 1e6:.1f} us"


def _foam() -> tuple[float, str]:
    foam = floor_module.foam_step_s()
    return foam, f"foam step {foam * 1e6:.1f} us"


def _link(quick: bool) -> list[Figure]:
    from forcelearn.tools.benchmarks.link import measure
    from forcelearn.tools.benchmarks.protocol_floors import link_move_exchange_s

    echo, floor = _echo()
    bare = link_move_exchange_s(500 if quick else 2000)
    p50 = float(np.percentile(measure(500 if quick else 2000, 100), 50))
    return [
        Figure("link move exchange, bare (protocol floor)", bare * 1e6, "us", bare / (2 * echo),
               "/ (2 x pty echo)", "-", floor),
        Figure("link move round trip p50", p50 * 1e6, "us", p50 / (2 * echo),
               "/ (2 x pty echo)", "<= 1.3", floor),
        Figure("link move round trip p50 / its protocol floor", p50 * 1e6, "us", p50 / bare,
               "/ bare exchange", "-", f"bare exchange {bare * 1e6:.1f} us"),
    ]


def _jr3(quick: bool) -> list[Figure]:
    import statistics

    from forcelearn.tools.benchmarks.jr3 import measure
    from forcelearn.tools.benchmarks.protocol_floors import jr3_sync_exchanges_per_s

    trips = floor_module.can_round_trips_per_s()
    bare = jr3_sync_exchanges_per_s()
    rate = statistics.median(measure(500 if quick else 2000, seed) for seed in range(3))
    can = f"CAN {trips:,.0f} round trips/s"
    return [
        Figure("JR3 sync exchange, bare (protocol floor)", bare, "exchanges/s", bare / trips,
               "/ CAN round trips/s", "-", can),
        Figure("JR3 single read (sync)", rate, "reads/s", rate / trips,
               "/ CAN round trips/s", ">= 0.9", can),
        Figure("JR3 single read / its protocol floor", rate, "reads/s", rate / bare,
               "/ bare exchanges/s", "-", f"bare exchange {bare:,.0f} /s"),
    ]


def _env(seconds: float) -> list[Figure]:
    from forcelearn.tools.benchmarks.surface_env import measure

    echo, floor = _echo()
    measured = measure(seconds)
    rate, cpu_rate = measured.steps_per_s, measured.steps_per_cpu_s
    return [
        Figure("Surface-v0 steps", rate, "steps/s", 1.0 / (rate * echo),
               "step / pty echo", "500 steps/s (a host of 255 us echo)", floor),
        Figure("Surface-v0 steps per CPU s", cpu_rate, "steps/CPU s", 1.0 / (cpu_rate * echo),
               "step CPU / pty echo", "500 steps/s", floor),
    ]


def _vec(quick: bool) -> list[Figure]:
    if importlib.util.find_spec("forcelearn.envs.surface_vec") is None:
        return []
    from forcelearn.tools.benchmarks.surface_vec import measure

    foam, floor = _foam()
    rate = measure(64, 1.0 if quick else 3.0)
    return [Figure("SurfaceVec-v0 steps, N = 64", rate, "env steps/s", rate * foam,
                   "x foam step s", ">= 100,000 steps/s", floor)]


@dataclass(frozen=True)
class CellRun:
    """One emulated cell's run: its trials' cell time, and the wall and CPU time it took.

    ``steady_*``: the trials after the first only (from the first trial's end
    to the last's): no probe, no first-use imports, what each further trial of
    a long run costs.
    """

    cell_s: float
    wall_s: float
    cpu_s: float
    steps: int
    steady_cell_s: float = math.nan
    steady_wall_s: float = math.nan
    steady_cpu_s: float = math.nan
    steady_steps: int = 0


def _cell_run(config: Path | None, trials: int) -> CellRun:
    """``forcelearn run``'s code path, timed from its start to its last trial's end."""
    from forcelearn.tools.experiments.surface_run import execute
    from forcelearn.tools.experiments.surface_state import prepare_run

    ends: list[tuple[float, float, float, int]] = []  # CPU, wall, trial's cell time, steps

    def trial_end(record: Any, _: object) -> None:
        ends.append((time.process_time(), time.perf_counter(), record.cell_time_s, record.steps))

    with tempfile.TemporaryDirectory(prefix="forcelearn-bench-all-") as tmp:
        surface_run, _ = prepare_run(config, Path(tmp), trials, 0, False)
        cpu0 = time.process_time()
        summary = execute(surface_run, None, on_trial=trial_end)
    run = CellRun(float(summary["cell_time_s"]), float(summary["wall_s"]),
                  (ends[-1][0] if ends else time.process_time()) - cpu0, int(summary["steps"]))
    if len(ends) < 2:
        return run
    later = ends[1:]
    return replace(run, steady_cell_s=sum(e[2] for e in later),
                   steady_wall_s=ends[-1][1] - ends[0][1], steady_cpu_s=ends[-1][0] - ends[0][0],
                   steady_steps=sum(e[3] for e in later))


def _cells(trials: int, examples: Path) -> list[Figure]:
    runs: dict[str, CellRun] = {}
    for label, name in CELL_CONFIGS.items():
        config = None if name is None else examples / Path(name).name
        runs[label] = run = _cell_run(config, trials)
        print(f"    {label}: real-time factor {run.cell_s / run.wall_s:.2f} (wall), "
              f"{run.cell_s / run.cpu_s:.2f} (CPU), {run.steps / run.cpu_s:.1f} steps per CPU s; "
              f"trials after the first: {run.steady_cell_s / run.steady_cpu_s:.2f} (CPU), "
              f"{run.steady_steps / run.steady_cpu_s:.1f} steps per CPU s, load {_load():.2f}",
              flush=True)
    base = runs["link + JR3"]
    floor = "the link + JR3 cell, same run"
    figures = []
    for label, run in runs.items():
        target = ">= 0.67 (within 1.5x)" if run is not base else "-"
        figures += [
            Figure(f"cell {label}: real-time factor (wall)", run.cell_s / run.wall_s,
                   "x real time", (run.cell_s / run.wall_s) / (base.cell_s / base.wall_s),
                   "/ link + JR3", target, floor),
            Figure(f"cell {label}: real-time factor (CPU)", run.cell_s / run.cpu_s,
                   "x real time", (run.cell_s / run.cpu_s) / (base.cell_s / base.cpu_s),
                   "/ link + JR3", target, floor),
            Figure(f"cell {label}: steps per CPU s", run.steps / run.cpu_s, "steps/s",
                   (run.steps / run.cpu_s) / (base.steps / base.cpu_s), "/ link + JR3", target,
                   floor),
            Figure(f"cell {label}: trials after the first, real-time factor (CPU)",
                   run.steady_cell_s / run.steady_cpu_s, "x real time",
                   (run.steady_cell_s / run.steady_cpu_s) / (base.steady_cell_s
                                                             / base.steady_cpu_s),
                   "/ link + JR3", target, floor),
            Figure(f"cell {label}: trials after the first, steps per CPU s",
                   run.steady_steps / run.steady_cpu_s, "steps/s",
                   (run.steady_steps / run.steady_cpu_s) / (base.steady_steps
                                                            / base.steady_cpu_s),
                   "/ link + JR3", target, floor),
        ]
    return figures


def _learner(quick: bool) -> Figure:
    from forcelearn.tools.benchmarks.learner import measure_batch

    foam, floor = _foam()
    rate = max(measure_batch(20_000 if quick else 100_000, 64, seed) for seed in range(2))
    return Figure("batched SRV learner, N = 64", rate, "steps/s", rate * foam,
                  "x foam step s", ">= 100,000 steps/s", floor)


def _contour(quick: bool) -> Figure:
    from forcelearn.tools.benchmarks.contour import measure

    foam, floor = _foam()
    rate, _ = measure(30 if quick else 100, 64)
    return Figure("contour simulation, N = 64", rate, "steps/s", rate * foam,
                  "x foam step s", ">= 100,000 steps/s", floor)


def _number(value: float) -> str:
    return f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"


def table(fl: floor_module.Floors, figures: list[Figure], load: float = 0.0) -> str:
    """The floors (at the start) and the figures with the floor each used, as Markdown."""
    lines = [
        "| floor | value |", "|---|---|",
        f"| host load average (1 min) at the start | {load:.2f} |",
        f"| pty echo round trip p50 | {fl.pty_echo_s * 1e6:.1f} us |",
        f"| python-can virtual bus round trips | {fl.can_round_trips_per_s:,.0f} /s |",
        f"| numpy foam-law step, 64 cells | {fl.foam_step_s * 1e6:.1f} us |",
        "",
        "| figure | value | its floor (just before it) | ratio | ratio is | target | load |",
        "|---|---|---|---|---|---|---|",
    ]
    lines += [f"| {f.name} | {_number(f.value)} {f.unit} | {f.floor} | {f.ratio:.3g} | "
              f"{f.ratio_means} | {f.target} | {f.load:.1f} |" for f in figures]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Measure the floors, then every figure, and print the table."""
    load = _load()
    print(f"floors... (load {load:.2f})", flush=True)
    fl = floor_module.measure()
    print(f"  pty echo {fl.pty_echo_s * 1e6:.1f} us, CAN {fl.can_round_trips_per_s:,.0f} "
          f"round trips/s, foam step {fl.foam_step_s * 1e6:.1f} us", flush=True)
    quick, skip = args.quick, set(args.skip)
    seconds = 3.0 if quick else args.seconds
    trials = 2 if quick else args.trials
    jobs: list[tuple[str, Callable[[], Figure | list[Figure]]]] = [
        ("link", lambda: _link(quick)),
        ("jr3", lambda: _jr3(quick)),
        ("env", lambda: _env(seconds)),
        ("vec", lambda: _vec(quick)),
        ("cells", lambda: _cells(trials, args.examples)),
        ("learner", lambda: _learner(quick)),
        ("contour", lambda: _contour(quick)),
    ]
    figures: list[Figure] = []
    for name, job in jobs:
        if name not in skip:
            figures += _timed(name, job)
    print()
    print(table(fl, figures, load))
    if args.json:
        args.json.write_text(json.dumps(
            {"floors": asdict(fl), "load": load, "figures": [asdict(f) for f in figures]},
            indent=1) + "\n")
    return 0
