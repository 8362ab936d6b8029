"""A random-instant fault sweep of the path task, judged by the emulator's physics.

Not a test (pytest does not collect it): ``python tests/tools/path_fault_sweep.py FIRST LAST``
runs seeds FIRST..LAST-1, one JSON line each. Each run: the cylinder example (27 points, 3
passes after the probe) on the computer link with a JR3 or a Net F/T, the example foam or an
8 N/mm one at 29.4 N, and one fault at a random reading after the probe: a sensor reboot, a
bias step of 1-8 N down or up, or a sensor silence that lifts within 1-3 restarts. Judged:
the true contact force against ``[safety] max_force_n`` (every physics tick), zeros taken in
contact, and every used reading in contact (of a pass the run booked, not voided) against the
true force along the tool's axis, in sigma of one sample's noise.
"""

from __future__ import annotations

import dataclasses
import json
import random
import sys
import tempfile
import traceback
from pathlib import Path
from typing import Any
from unittest import mock

sys.path.insert(0, str(Path(__file__).resolve().parent))

import test_path_faults as faults

from forcelearn.errors import ForcelearnError
from forcelearn.site import CellSession
from forcelearn.tools.experiments import path_run
from forcelearn.tools.experiments.fault_recovery import read_events
from forcelearn.tools.experiments.path_state import prepare_path_run

NETFT = ('[sensor]\nkind = "netft"\nhost = "emulated"\ncalibration_source = "http"\n'
         'zero_on_init = true\n[filter]\nmeasurement_variance_n2 = 0.0025\n')
STIFF = "[emulator.sponge]\nstiffness_n_per_mm = 8.0\n"
KINDS = ("reboot", "bias_down", "bias_up", "silence", "reboot", "bias_down")
LIMIT_N = 60.0


def one(seed: int, root: Path) -> dict[str, Any]:
    """One run with one fault (the module docstring); its judged outcome."""
    rng = random.Random(seed)
    sensor = rng.choice(["jr3", "netft"])
    material = rng.choice(["default", "stiff8"])
    kind = rng.choice(KINDS)
    tmp = root / f"r{seed}"
    tmp.mkdir()
    config = faults.cylinder_config(tmp, extra=(NETFT if sensor == "netft" else "")
                                    + (STIFF if material == "stiff8" else ""))
    text = config.read_text()
    if sensor == "netft":
        text = text.replace("emulated-jr3-cal.toml", "emulated-netft-cal.toml")
    if material == "stiff8":
        text = text.replace("desired_force_n = 19.6133", "desired_force_n = 29.42")
    config.write_text(text)
    out = tmp / "run"
    fire_at, size = rng.randint(1, 110), rng.uniform(1.0, 8.0)
    state: dict[str, Any] = {"n": 0, "fired": None, "undo": None}
    pending: list[float] = []
    used: list[float] = []
    watched = faults.Watched()

    def before(session: CellSession) -> None:
        if not (out / "probe.csv").exists():
            return
        state["n"] += 1
        if state["fired"] is None and state["n"] == fire_at:
            state["fired"] = (session.cell.stage,  # type: ignore[union-attr]
                              round(faults.true_along_axis_n(session), 2))
            emulator = session.sensor_emulator
            if kind == "reboot":
                (emulator.inject_bootup if sensor == "jr3" else emulator.inject_reboot)()
            elif kind.startswith("bias"):
                faults.shift_bias(session, size if kind == "bias_up" else -size)
            else:
                emulator.set_faults(dataclasses.replace(emulator.faults, silent=True))
                state["undo"] = [rng.randint(1, 3), lambda: emulator.set_faults(
                    dataclasses.replace(emulator.faults, silent=False))]

    watched.before_reading = before
    base = watched.session_class()

    class Judged(base):  # type: ignore[misc,valid-type]
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            cell = self.cell
            measure, zero = cell.measure_force_n, cell.zero_in_free_space

            def judged(samples: int | None = None) -> float:
                reading = measure(samples)
                truth = faults.true_along_axis_n(self)
                if truth > 1.0 and (samples is None or samples > 1):
                    pending.append(abs(reading - truth))
                return reading

            def zeroed() -> float:
                undo = state["undo"]
                if undo is not None:  # a silence lifts within 1-3 restarts
                    undo[0] -= 1
                    if undo[0] <= 0:
                        undo[1]()
                        state["undo"] = None
                return float(zero())

            cell.measure_force_n = judged
            cell.zero_in_free_space = zeroed

    class Writer(path_run.RecordsWriter):
        def write_trial(self, records: Any) -> None:
            used.extend(pending)
            pending.clear()
            super().write_trial(records)

    void = path_run.PathRecovery._void

    def voided(self: path_run.PathRecovery, trial: int, exc: ForcelearnError) -> None:
        pending.clear()
        void(self, trial, exc)

    run, _ = prepare_path_run(config, None, out, 3, seed, 25, resume=False)
    error = ""
    with mock.patch.object(path_run, "CellSession", Judged), \
            mock.patch.object(path_run, "RecordsWriter", Writer), \
            mock.patch.object(path_run.PathRecovery, "_void", voided):
        try:
            path_run.execute(run, None, figures=False)
        except ForcelearnError as exc:
            error = type(exc).__name__
    first = watched.sessions[0]
    axis = first.cell.force_filter.config.axis  # type: ignore[union-attr]
    sigma_n = float(first.sensor_emulator.model.params.noise_std[axis])
    return {"seed": seed, "sensor": sensor, "material": material, "kind": kind,
            "size": round(size, 2) if kind.startswith("bias") else None,
            "fired": state["fired"], "events": [(e["error"], e["action"]) for e in
                                                read_events(out)],
            "error": error, "max_true_n": round(watched.max_contact_n, 2),
            "over": watched.max_contact_n > LIMIT_N,
            "zeros_in_contact": sum(t.zeros_in_contact for t in watched.truths),
            "used": len(used), "beyond_3sigma": sum(e > 3 * sigma_n for e in used),
            "worst_sigma": round(max(used) / sigma_n, 2) if used else None}


def main() -> None:
    """Run the seeds of the command line; print one JSON line each."""
    root = Path(tempfile.mkdtemp(prefix="path-fault-sweep"))
    for seed in range(int(sys.argv[1]), int(sys.argv[2])):
        try:
            print(json.dumps(one(seed, root)), flush=True)
        except Exception:  # a crash is a finding: print it, go on
            print(json.dumps({"seed": seed, "crash": traceback.format_exc()[-600:]}), flush=True)


if __name__ == "__main__":
    main()
