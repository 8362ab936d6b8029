"""``forcelearn probe``: find the surface (contact Y, stiffness) and the output map a run would use.

Opens the cell as ``forcelearn run`` would (emulated by default), runs only
the force-guarded probe of :mod:`forcelearn.tasks.surface_probe`, and writes
``probe.csv``, ``probe.json`` and ``probe.png`` to ``--out``. The robot ends
at the retract plane. Exit 1 with a one-line reason when no surface is found
or the desired force is out of reach.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

from forcelearn.press_guard import PressGuard
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.surface_probe import SurfaceProbe, map_from_probe
from forcelearn.tools.experiments.fault_recovery import RunRecovery
from forcelearn.tools.experiments.surface_outputs import write_probe_files


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn probe``."""
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")
    parser.add_argument("--seed", type=int, help="emulated sensor noise seed (default [run] seed)")
    parser.add_argument("--out", type=Path, help="output folder (default runs/probe-<time>)")


def run(args: argparse.Namespace) -> int:
    """Probe the surface and print the fits and the chosen output map as JSON."""
    config = load_cell_config(args.config)
    out = args.out or Path("runs") / time.strftime("probe-%Y%m%d-%H%M%S")
    seed = args.seed if args.seed is not None else config.seed
    with CellSession(config, seed=seed) as session:
        assert session.cell is not None
        cell = session.cell
        cell.press_guard = PressGuard(config.safety.max_force_n,
                                      config.task.press_stiffness_n_per_mm,
                                      cell.force_filter.measurement_variance_n2 ** 0.5)
        checks = RunRecovery(out, cell, config.task.retract_y_mm, config.safety.max_step_mm,
                             zero_check=config.task.zero_check, watch=False)
        probe = SurfaceProbe(  # as the run's: guarded, a zero check at each point
            cell,
            config.task,
            config.probe,
            config.safety.max_step_mm,
            config.safety.workspace_min_mm[1],
            checks.probe_zero_check,
        )
        try:  # the run's own probe, with its refinement where the map follows the surface
            result, choice = map_from_probe(probe)
        finally:
            write_probe_files(out, probe.result, None)
    write_probe_files(out, result, choice)
    print(
        json.dumps(
            {
                "fits": [dataclasses.asdict(f) for f in result.fits],
                "output_map": dataclasses.asdict(choice),
            },
            indent=2,
        )
    )
    print(f"probe directory: {out}")
    return 0
