"""``forcelearn bench NAME``: speed benchmarks that print figures (never timed tests).

Each benchmark lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; this table lists them.
"""

from __future__ import annotations

import argparse
import importlib

_PACKAGE = "forcelearn.tools.benchmarks."

# name -> (module, one-line help)
BENCHMARKS: dict[str, tuple[str, str]] = {
    "all": (_PACKAGE + "all", "every figure below beside the machine's floors, as ratios"),
    "learner": (_PACKAGE + "learner", "SRV learner steps/s (act + learn, 2-D grid)"),
    "contour": (
        _PACKAGE + "contour",
        "§4 contour simulation controller steps/s, single or batched seeds",
    ),
    "link": (_PACKAGE + "link", "computer-link move round trip p50/p99 over a pty"),
    "jr3": (_PACKAGE + "jr3", "JR3 sync-mode paired samples/s, virtual CAN bus"),
    "egm": (_PACKAGE + "egm", "EGM 4 ms loop period, jitter and reply latency, UDP"),
    "netft": (_PACKAGE + "netft", "Net F/T records/s and p99 latency, loopback UDP"),
    "surface-env": (_PACKAGE + "surface_env", "Gymnasium forcelearn/Surface-v0 steps/s"),
    "surface-vec": (_PACKAGE + "surface_vec", "forcelearn/SurfaceVec-v0 env steps/s, N cells"),
    "cell": (_PACKAGE + "cell", "§5 run on the emulated cell: cell time / wall time"),
    "live": (_PACKAGE + "live", "§5 run with --live and a browser vs without"),
    "twin": (_PACKAGE + "twin", "forcelearn twin's fit wall time on a 300-trial run's records"),
    "baselines": (
        _PACKAGE + "baselines",
        "baselines study: CPU and wall ms per step of each method on the emulated cell",
    ),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Attach the benchmark's name and its own options (parsed by the benchmark itself).

    Only the chosen benchmark's module is imported (several pull in gymnasium, cma or
    the browser client), so ``forcelearn bench link`` costs the link's imports alone.
    """
    listing = "\n".join(f"  {name:<10} {help_text}" for name, (_, help_text) in BENCHMARKS.items())
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = "benchmarks:\n" + listing
    parser.add_argument(
        "benchmark",
        choices=sorted(BENCHMARKS),
        metavar="BENCHMARK",
        help="which benchmark to run (listed below)",
    )
    parser.add_argument(
        "options",
        nargs=argparse.REMAINDER,
        help="the benchmark's own options (forcelearn bench NAME --help)",
    )


def run(args: argparse.Namespace) -> int:
    """Import the chosen benchmark, parse its options and run it."""
    module_name, help_text = BENCHMARKS[args.benchmark]
    module = importlib.import_module(module_name)
    bench = argparse.ArgumentParser(
        prog=f"forcelearn bench {args.benchmark}", description=help_text
    )
    module.add_arguments(bench)
    return int(module.run(bench.parse_args(args.options)) or 0)
