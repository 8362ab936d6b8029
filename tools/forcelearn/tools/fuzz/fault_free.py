"""Fault-free runs, judged by the physics: false voids of the zero check, the press guard's cuts.

``python -m forcelearn.tools.fuzz.fault_free --cells link+jr3 link+netft --materials default
stiff8 --seeds 0 1 --trials 10 --out F.csv`` runs each example cell (the default
``[task] zero_check = true``) on each material, with and without the probe, and writes a
row per run as it ends (a partial study still says something): the zero checks made, the
voids (a fault-free run should have none), the largest check against its bound, the
largest true contact force against ``[safety] max_force_n``, the moves the press guard cut,
the presses made again from a fresh zero (``Cell.refresh_zero``), the largest error of a
used reading in the sensor's noise sigma, convergence and the run's cell time. Materials
are ``--set`` overrides of :data:`MATERIALS`.
"""

from __future__ import annotations

import argparse
import csv
import json
import random
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from unittest import mock

from forcelearn.cell import Cell
from forcelearn.press_guard import press_agreement_n
from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.fault_recovery import RunRecovery, read_events
from forcelearn.tools.fuzz.fault_campaign import CELLS, examples_config, injecting
from forcelearn.tools.fuzz.fault_inject import Injector, Truth

STIFF15_START = ("task.start_mm=[900.0, 0.0, 0.0]", "task.output_scale_mm=0.5",
                 "task.max_offset_mm=3.0")
"""A 15 N/mm foam's cold start as a site would set it (the default's y = -4 mm presses it to
75 N: the press guard refuses that first press and the run ends on ForceLimitExceeded)."""
MATERIALS: dict[str, tuple[str, ...]] = {
    "default": (),
    "stiff8": ("emulator.sponge.stiffness_n_per_mm=8.0", "task.desired_force_n=29.42"),
    "stiff8-small": ("emulator.sponge.stiffness_n_per_mm=8.0", "task.desired_force_n=5.0",
                     "probe.approach_step_mm=0.25"),  # 1 mm steps pass 5 N at the first contact
    "stiff15": ("emulator.sponge.stiffness_n_per_mm=15.0", "task.desired_force_n=29.42",
                *STIFF15_START),
    "stiff15-small": ("emulator.sponge.stiffness_n_per_mm=15.0", "task.desired_force_n=5.0",
                      *STIFF15_START),
    "hyst0.3": ("emulator.sponge.hysteresis_loss=0.3", "emulator.sponge.stiffness_n_per_mm=1.2",
                "task.desired_force_n=24.5"),
    "hyst0.3-k2": ("emulator.sponge.hysteresis_loss=0.3",),
    "friction0.3": ("emulator.sponge.friction_coefficient=0.3",),
}
"""Materials by name: ``table.key=value`` overrides of the example cells."""

FIELDS = ("cell", "material", "probe", "seed", "trials", "checks", "voids", "events",
          "worst_check_ratio", "first_presses_twice", "worst_press_ratio", "worst_check_n",
          "max_contact_n", "max_force_n", "guard_cuts", "zero_refreshes",
          "worst_used_n", "sigma_n", "beyond_3sigma", "converged_trial", "cell_time_s",
          "wall_s")


def one_run(cell: str, material: str, probe: bool, seed: int, trials: int,
            folder: Path) -> dict[str, Any]:
    """One fault-free run; its row of :data:`FIELDS`."""
    config = examples_config(cell, folder, trials, probe, MATERIALS[material])
    checks: list[tuple[float, float]] = []
    check_zero = Cell.check_zero

    def recorded(cell_: Cell, bound_n: Any) -> tuple[float, float]:
        force, bound = check_zero(cell_, bound_n)
        checks.append((force, bound))
        return force, bound

    presses: list[list[float]] = []
    press_in = RunRecovery.press_in

    def pressed_in(recovery: RunRecovery, press: Any) -> float:
        made: list[float] = []
        presses.append(made)

        def noted() -> float:
            made.append(press())
            return made[-1]

        return press_in(recovery, noted)

    truths: list[Truth] = []
    started = time.perf_counter()
    with mock.patch.object(Cell, "check_zero", recorded), \
            mock.patch.object(RunRecovery, "press_in", pressed_in), \
            injecting(Injector({}, random.Random(0)), 1e9, truths):
        run, checkpoint = run_state.prepare_run(config, folder / "run", None, seed, resume=False)
        engine.execute(run, checkpoint)
        guard = truths[0].session.cell.press_guard
        refreshes = truths[0].session.cell.zero_refreshes
    truth = truths[0]
    truth.finish()
    summary = json.loads((folder / "run" / "summary.json").read_text())
    events = read_events(folder / "run")
    return {
        "cell": cell, "material": material, "probe": probe, "seed": seed, "trials": trials,
        "checks": len(checks), "voids": sum(e["action"] == "voided" for e in events),
        "events": len(events),
        "worst_check_ratio": round(max((abs(f) / b for f, b in checks), default=0.0), 3),
        "first_presses_twice": sum(len(p) == 2 for p in presses),
        "worst_press_ratio": round(max((abs(p[1] - p[0]) / press_agreement_n(p[0])
                                        for p in presses if len(p) == 2), default=0.0), 3),
        "worst_check_n": round(max((abs(f) for f, _ in checks), default=0.0), 3),
        "max_contact_n": round(truth.max_contact_n, 2),
        "max_force_n": run.config.safety.max_force_n,
        "guard_cuts": 0 if guard is None else guard.cuts,
        "zero_refreshes": refreshes,
        "worst_used_n": round(truth.worst_used_n, 3), "sigma_n": round(truth.sigma_n, 4),
        "beyond_3sigma": truth.beyond_3sigma, "converged_trial": summary.get("converged_trial"),
        "cell_time_s": summary.get("cell_time_s"),
        "wall_s": round(time.perf_counter() - started, 1),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Run the study; exit 1 if a run voided a trial or passed the force limit."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", nargs="+", default=["link+jr3"], choices=list(CELLS))
    parser.add_argument("--materials", nargs="+", default=["default"], choices=list(MATERIALS))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--probe", choices=("both", "yes", "no"), default="both")
    parser.add_argument("--out", type=Path, required=True, help="CSV, a row per run")
    args = parser.parse_args(argv)
    probes = {"both": (True, False), "yes": (True,), "no": (False,)}[args.probe]
    failed = False
    with open(args.out, "w", newline="") as handle:
        writer = csv.DictWriter(handle, FIELDS)
        writer.writeheader()
        for material in args.materials:
            for cell in args.cells:
                for probe in probes:
                    for seed in args.seeds:
                        with tempfile.TemporaryDirectory() as tmp:
                            row = one_run(cell, material, probe, seed, args.trials, Path(tmp))
                        writer.writerow(row)
                        handle.flush()
                        print(row, flush=True)
                        failed |= row["voids"] > 0 or row["max_contact_n"] > row["max_force_n"]
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
