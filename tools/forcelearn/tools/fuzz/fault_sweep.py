"""One fault at every instant of a run's first trials, on stiff foams: the worst instant found.

``python -m forcelearn.tools.fuzz.fault_sweep --cells link+jr3 --materials stiff8 stiff15
--faults reboot bias_jump --every 3 --out W.csv`` runs, per cell, material and fault, a
fault-free run (2 trials of 8 steps, cold: no probe, unless ``--probe``) to count its device
calls, then one run per ``--every``-th call with that one fault fired there (a bias jump of the
largest size, read as less force than there is: the direction that makes the cell press
harder), each resumed until it completes, and writes a row per run as it ends: the largest
true contact force against ``[safety] max_force_n``, used readings beyond 3 sigma of the
sensor's noise, zeros in contact, how the run went. Exit 1 if any passed the limit.
"""

from __future__ import annotations

import argparse
import csv
import random
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from forcelearn.tools.fuzz.fault_campaign import (
    CELLS,
    cell_config,
    fault_free_run,
    one_run,
    report_row,
)
from forcelearn.tools.fuzz.fault_free import MATERIALS
from forcelearn.tools.fuzz.fault_inject import SENSOR_FAULTS, Injector

FIELDS = ("cell", "material", "probe", "fault", "size", "tick", "of_ticks", "max_contact_n",
          "free_max_contact_n", "over_limit", "beyond_3sigma", "worst_used_n", "zeros_in_contact",
          "sessions", "finished", "ends", "resumed_from")


class Largest(random.Random):
    """Draws every fault size at its largest (or ``size``), a bias jump upwards on the axis."""

    def __init__(self, size: float | None = None) -> None:
        super().__init__(0)
        self.size = size

    def uniform(self, a: float, b: float) -> float:
        """The upper end (or the size asked for)."""
        return b if self.size is None else self.size

    def choice(self, seq: Any) -> Any:
        """The last one (+1: a bias up on Fy reads as less normal force, sign -1)."""
        return seq[-1]


def sweep(cell: str, material: str, probe: bool, fault: str, every: int, seed: int,
          folder: Path, size: float | None = None) -> list[dict[str, Any]]:
    """The rows of one cell, material and fault, one per instant."""
    config = cell_config(cell, folder, 2, 8, probe, MATERIALS[material])
    ticks, _, free_max = fault_free_run(config, folder / "free", seed)
    rows = []
    for tick in range(1, ticks + 1, every):
        injector = Injector({tick: [("sensor", fault)]}, Largest(size))
        report = one_run(cell, config, folder / f"t{tick}", seed, ticks, 0, 0, 1e9,
                         injector=injector)
        rows.append({
            "cell": cell, "material": material, "probe": probe, "fault": fault, "size": size,
            "tick": tick,
            **report_row(report, ticks, free_max),
        })
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sweep; exit 1 if a run's true force passed the limit."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", nargs="+", default=["link+jr3"], choices=list(CELLS))
    parser.add_argument("--materials", nargs="+", default=["stiff8"], choices=list(MATERIALS))
    parser.add_argument("--faults", nargs="+", default=["reboot", "bias_jump"],
                        choices=list(SENSOR_FAULTS))
    parser.add_argument("--every", type=int, default=3, help="a run per this many device calls")
    parser.add_argument("--probe", action="store_true", help="runs start with the probe")
    parser.add_argument("--sizes", type=float, nargs="+", default=[None],
                        help="bias jumps of these sizes, N (default: the largest, 8 N)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True, help="CSV, a row per run")
    args = parser.parse_args(argv)
    over = 0
    with open(args.out, "w", newline="") as handle:
        writer = csv.DictWriter(handle, FIELDS)
        writer.writeheader()
        for material in args.materials:
            for cell in args.cells:
                for fault, size in [(f, z) for f in args.faults for z in args.sizes]:
                    with tempfile.TemporaryDirectory() as tmp:
                        rows = sweep(cell, material, args.probe, fault, args.every, args.seed,
                                     Path(tmp), size)
                    writer.writerows(rows)
                    handle.flush()
                    over += sum(r["over_limit"] for r in rows)
                    worst = max(rows, key=lambda r: r["max_contact_n"])
                    print(f"{cell} {material} {fault} {size or ''}: {len(rows)} instants, "
                          f"max true force {worst['max_contact_n']} N (tick {worst['tick']}; "
                          f"fault-free {worst['free_max_contact_n']} N), over the limit {over}, "
                          "beyond "
                          f"3 sigma {sum(r['beyond_3sigma'] for r in rows)}", flush=True)
    return 1 if over else 0


if __name__ == "__main__":
    raise SystemExit(main())
