"""``forcelearn identify --config site.toml --out DIR``: the twin's identification run.

Runs the short, force-guarded plan of :mod:`forcelearn.tools.twin.identify` on the cell
(emulated by default): polled free-space moves of several lengths and speeds, a
free-space hold, a press held over time, press in and ease off. Writes
``DIR/identification.json``; ``forcelearn twin RUN_DIR --identification DIR`` uses it.
``--plan`` prints the plan and its cell time without moving anything; ``--design TWIN_JSON``
runs (or with ``--plan`` prints) a plan designed from a twin's uncertainties
(:mod:`forcelearn.tools.twin.designed`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn identify``."""
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")
    parser.add_argument("--seed", type=int, help="emulated sensor noise seed (default [run] seed)")
    parser.add_argument("--out", type=Path, help="output folder (default runs/identify-<time>)")
    parser.add_argument("--plan", action="store_true",
                        help="print the plan and its cell time; move nothing")
    parser.add_argument("--design", type=Path, metavar="TWIN_JSON",
                        help="design the plan from a twin's uncertainties (forcelearn twin's "
                             "twin.json, or its folder): only the parts that determine what "
                             "it left undetermined; prints why, the cell time and the 1-sigma "
                             "it expects")


def run(args: argparse.Namespace) -> int:
    """Run the identification plan and write identification.json."""
    from forcelearn.site.config import load_cell_config
    from forcelearn.tools.twin.identify import (
        IdentifyPlan,
        run_identification,
        write_identification,
    )
    from forcelearn.tools.twin.identify_fit import BAND_MM, fit_timing, timing_document

    plan = IdentifyPlan()
    config = load_cell_config(args.config) if args.design or not args.plan else None
    if args.design is not None:
        from forcelearn.tools.twin.designed import design_from_file

        assert config is not None
        designed = design_from_file(args.design, config.task.desired_force_n)
        plan = designed.plan
        print(json.dumps(designed.document(), indent=2))
        if args.plan:
            return 0
    elif args.plan:
        print(json.dumps({"plan": dataclasses.asdict(plan),
                          "cell_time_s": round(plan.cell_time_s(), 1)}, indent=2))
        return 0
    assert config is not None
    out = args.out or Path("runs") / time.strftime("identify-%Y%m%d-%H%M%S")
    seed = args.seed if args.seed is not None else config.seed
    result = run_identification(config, plan, seed)
    path = write_identification(result, out)
    timing = fit_timing(result.moves, BAND_MM)
    if timing is not None:  # kept in the file: the twin and the study read it, not refit it
        path = write_identification(
            dataclasses.replace(result, timing=timing_document(timing, BAND_MM)), out)
    steps = sum(len(t.steps) for t in result.records)
    print(f"identification: {len(result.moves)} timed moves, {steps} force steps; "
          f"wrote {path}")
    if timing is not None:
        print("arm from the polled moves: " + ", ".join(
            f"{name} {value:.4g} ± {timing.sigmas[name]:.2g}"
            for name, value in timing.values.items()))
    return 0
