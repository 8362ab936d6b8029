"""``forcelearn bench NAME``: speed benchmarks that print figures (never timed tests).

Each benchmark lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; this table lists them.
"""

from __future__ import annotations

import argparse
import importlib

# name -> (module, one-line help)
BENCHMARKS: dict[str, tuple[str, str]] = {
    "learner": ("forcelearn.tools.bench_learner", "SRV learner steps/s (act + learn, 2-D grid)"),
    "contour": (
        "forcelearn.tools.bench_contour",
        "§4 contour simulation controller steps/s, single or batched seeds",
    ),
    "link": ("forcelearn.tools.bench_link", "computer-link move round trip p50/p99 over a pty"),
    "jr3": ("forcelearn.tools.bench_jr3", "JR3 sync-mode paired samples/s, virtual CAN bus"),
    "egm": ("forcelearn.tools.bench_egm", "EGM 4 ms loop period, jitter and reply latency, UDP"),
    "netft": ("forcelearn.tools.bench_netft", "Net F/T records/s and p99 latency, loopback UDP"),
    "cell": ("forcelearn.tools.bench_cell", "§5 run on the emulated cell: cell time / wall time"),
    "live": ("forcelearn.tools.bench_live", "§5 run with --live and a browser vs without"),
    "baselines": (
        "forcelearn.tools.bench_baselines",
        "baselines study: CPU and wall ms per step of each method on the emulated cell",
    ),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Attach one sub-parser per benchmark."""
    sub = parser.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    for name, (module_name, help_text) in BENCHMARKS.items():
        module = importlib.import_module(module_name)
        bench = sub.add_parser(name, help=help_text, description=help_text)
        module.add_arguments(bench)
        bench.set_defaults(_bench=module.run)


def run(args: argparse.Namespace) -> int:
    """Run the chosen benchmark."""
    return int(args._bench(args) or 0)
