"""Faults the campaign does not draw, at random instants of short runs, judged by the physics.

``python -m forcelearn.tools.fuzz.fault_extra --cells link+jr3 link+netft --materials stiff8
stiff8-small stiff15 hyst0.3 friction0.3 --runs 10 --seed 60 --out X.csv`` runs, per cell,
material and fault, ``--runs`` runs (2 trials of 8 steps, cold: no probe) with that one fault
fired at a random device call (seeded), each resumed until it completes, and writes a row per
run: the largest true contact force against ``[safety] max_force_n``, used readings beyond 3
sigma of the sensor's noise, zeros in contact, how the run went. Exit 1 if any passed the limit.

=================  ===========================================================
fault              what the emulator does
=================  ===========================================================
``drift``          the sensor's bias on the normal axis creeps by ``--drift-n``
                   (0.02 N) at every device call from then on, in the direction
                   that reads less force than there is (a warming sensor)
``stuck``          the sensor repeats its last sample (frozen data, sequence
                   numbers going on) for the next 3 to 30 device calls
``flicker``        the sensor falls silent every other device call for the next
                   4 to 12 (an intermittent cable)
``reboot_check``   the sensor reboots at the next zero check, as it reads
``jump_backout``   a bias jump of 1 to 8 N, read as less force, as the tool next
                   backs out of contact (the move up that ends a press)
=================  ===========================================================
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import random
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.protocols.jr3_can.codec import Frame
from forcelearn.tools.fuzz.fault_campaign import (
    CELLS,
    cell_config,
    fault_free_run,
    one_run,
    report_row,
)
from forcelearn.tools.fuzz.fault_free import MATERIALS
from forcelearn.tools.fuzz.fault_inject import Injector, Truth

EXTRA_FAULTS = ("drift", "stuck", "flicker", "reboot_check", "jump_backout")
DRIFT_N_PER_CALL = 0.02
"""The default drift, N per device call (about 0.1 N/s of cell time: a warming sensor)."""
FIELDS = ("cell", "material", "fault", "seed", "tick", "of_ticks", "max_contact_n",
          "free_max_contact_n", "over_limit", "beyond_3sigma", "worst_used_n",
          "zeros_in_contact", "sessions", "finished", "ends", "resumed_from")


class ExtraInjector(Injector):
    """The campaign's injector with the faults of this module (see its table).

    Args:
        plan: tick -> list of ("sensor", fault kind).
        rng: draws the faults' sizes and lengths.
        drift_n: the drift per device call, N.
    """

    def __init__(self, plan: dict[int, list[tuple[str, str]]], rng: random.Random,
                 drift_n: float = DRIFT_N_PER_CALL) -> None:
        super().__init__(plan, rng)
        self.drift_n = drift_n
        self.drifting = False
        self._armed: set[str] = set()

    def attach(self, session: Any, truth: Truth) -> None:
        """As the campaign's, and the zero check and the moves watched for armed faults."""
        super().attach(session, truth)
        cell = session.cell
        check_zero, move_to = cell.check_zero, cell.move_to

        def checked(bound_n: Any) -> tuple[float, float]:
            if "reboot_check" in self._armed:
                self._armed.discard("reboot_check")
                self._sensor_reboot()
            result: tuple[float, float] = check_zero(bound_n)
            return result

        def moved(pose: Any, settle: bool = True) -> None:
            here = cell.known_pose
            if ("jump_backout" in self._armed and here is not None
                    and pose.y_mm > here.y_mm and truth.contact_n() > 0.0):
                self._armed.discard("jump_backout")
                self._jump(self.rng.uniform(1.0, 8.0))
            move_to(pose, settle)

        cell.check_zero = checked
        cell.move_to = moved

    def _step(self) -> None:
        super()._step()
        if self.drifting:
            self._jump(self.drift_n)

    def _jump(self, size_n: float) -> None:
        """The bias on the normal axis moves by ``size_n`` (read as that much less force)."""
        model = self.session.sensor_emulator.model
        state = model.state_dict()
        bias = np.asarray(state["bias"], dtype=float).copy()
        bias[self.session.cell.force_filter.config.axis] += size_n
        state["bias"] = bias
        model.load_state_dict(state)
        assert self.truth is not None
        self.truth.jumped = True

    # ---- the faults ------------------------------------------------------------------------
    def _sensor_drift(self) -> None:
        self.drifting = True

    def _sensor_reboot_check(self) -> None:
        self._armed.add("reboot_check")

    def _sensor_jump_backout(self) -> None:
        self._armed.add("jump_backout")

    def _sensor_flicker(self) -> None:
        emulator = self.session.sensor_emulator
        for i in range(self.rng.randint(4, 12)):
            silent = i % 2 == 0
            self._undo.append((self.tick + i, lambda s=silent: emulator.set_faults(
                dataclasses.replace(emulator.faults, silent=s))))
        self._undo.append((self.tick + 13, lambda: emulator.set_faults(
            dataclasses.replace(emulator.faults, silent=False))))
        emulator.set_faults(dataclasses.replace(emulator.faults, silent=True))

    def _sensor_stuck(self) -> None:
        emulator, until = self.session.sensor_emulator, self.tick + self.rng.randint(3, 30)
        if hasattr(emulator, "frame_hook"):  # JR3: each data frame as it last was
            frozen: dict[int, bytes] = {}

            def stuck(frame: Frame) -> Frame | None:
                if self.tick >= until:
                    return frame
                data = frozen.setdefault(frame.arbitration_id, bytes(frame.data))
                return Frame(frame.arbitration_id, data)

            emulator.frame_hook = stuck
            self._undo.append((until, lambda: setattr(emulator, "frame_hook", None)))
            return
        held: list[Any] = []  # Net F/T: every record with the first one's counts

        def frozen_counts(records: list[Any]) -> list[Any]:
            if self.tick >= until or not records:
                return records
            if not held:
                held.append(records[0].counts)
            return [dataclasses.replace(r, counts=held[0]) for r in records]

        emulator.records_hook = frozen_counts
        self._undo.append((until, lambda: setattr(emulator, "records_hook", None)))


def runs(cell: str, material: str, fault: str, count: int, seed: int, folder: Path,
         drift_n: float) -> list[dict[str, Any]]:
    """The rows of ``count`` runs of one cell, material and fault."""
    config = cell_config(cell, folder, 2, 8, False, MATERIALS[material])
    ticks, _, free_max = fault_free_run(config, folder / "free", seed)
    rng = random.Random(f"{seed}-{cell}-{material}-{fault}")
    rows = []
    for i in range(count):
        tick = rng.randint(1, ticks)
        injector = ExtraInjector({tick: [("sensor", fault)]}, random.Random(rng.random()),
                                 drift_n)
        report = one_run(cell, config, folder / f"r{i}", seed, ticks, 0, 0, 1e9,
                         injector=injector)
        rows.append({
            "cell": cell, "material": material, "fault": fault, "seed": seed, "tick": tick,
            **report_row(report, ticks, free_max),
        })
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Run the faults; exit 1 if a run's true force passed the limit."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", nargs="+", default=["link+jr3"], choices=list(CELLS))
    parser.add_argument("--materials", nargs="+", default=["stiff8"], choices=list(MATERIALS))
    parser.add_argument("--faults", nargs="+", default=list(EXTRA_FAULTS), choices=EXTRA_FAULTS)
    parser.add_argument("--runs", type=int, default=10, help="runs per cell, material, fault")
    parser.add_argument("--drift-n", type=float, default=DRIFT_N_PER_CALL,
                        help="the drift per device call, N")
    parser.add_argument("--seed", type=int, default=60)
    parser.add_argument("--out", type=Path, required=True, help="CSV, a row per run")
    args = parser.parse_args(argv)
    over = 0
    with open(args.out, "w", newline="") as handle:
        writer = csv.DictWriter(handle, FIELDS)
        writer.writeheader()
        for material in args.materials:
            for cell in args.cells:
                for fault in args.faults:
                    with tempfile.TemporaryDirectory() as tmp:
                        rows = runs(cell, material, fault, args.runs, args.seed, Path(tmp),
                                    args.drift_n)
                    writer.writerows(rows)
                    handle.flush()
                    over += sum(r["over_limit"] for r in rows)
                    worst = max(rows, key=lambda r: r["max_contact_n"])
                    print(f"{cell} {material} {fault}: {len(rows)} runs, max true force "
                          f"{worst['max_contact_n']} N (fault-free {worst['free_max_contact_n']} "
                          f"N), over the limit {sum(r['over_limit'] for r in rows)}, beyond 3 "
                          f"sigma {sum(r['beyond_3sigma'] for r in rows)}, finished "
                          f"{sum(r['finished'] for r in rows)}", flush=True)
    return 1 if over else 0


if __name__ == "__main__":
    raise SystemExit(main())
