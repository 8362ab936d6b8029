"""The real-foam study's plan, collection, page and figure, on made-up run directories."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from forcelearn.tools.results.materials import collect, plan
from forcelearn.tools.results.materials_page import STIFF_N_PER_MM, write_figure, write_page
from forcelearn.tools.twin.hidden_cells import write_hidden_cells


def _fake_run(out: Path, converged: int | None, rms: float) -> None:
    """A finished run directory: summary.json and trials.csv (20 trials)."""
    out.mkdir(parents=True)
    summary = {"converged": converged is not None, "converged_trial": converged,
               "in_band_at_end": converged is not None, "diagnosis": None if converged is not None
               else "hysteresis: ...", "output_map": {"approach_mm": 1.5}}
    (out / "summary.json").write_text(json.dumps(summary))
    rows = ["index,phase,steps,failed,mean_r,force_rms_n,start_force_n,cell_time_s"]
    rows += [f"{i},specialized,20,False,0.1,{rms},5.0,20.0" for i in range(20)]
    (out / "trials.csv").write_text("\n".join(rows) + "\n")


def test_the_study_plans_both_starts_and_the_designs_on_hysteretic_cells(tmp_path: Path) -> None:
    """Every cell with both starts; a hysteretic cell also with each design.

    In the order a stopped study still reports: the default start on every cell,
    then the designs, then the cold start on the hysteretic and stiff cells first.
    """
    cells, runs = tmp_path / "cells", tmp_path / "runs"
    write_hidden_cells(6, 40, cells)
    jobs = plan(cells, runs, ["direction", "direct"])
    truths = {p.stem.removesuffix(".truth"): json.loads(p.read_text())["sponge"]
              for p in cells.glob("*.truth.json")}
    hysteretic = {c for c, s in truths.items() if s["hysteresis_loss"] > 0}
    stiff = {c for c, s in truths.items() if s["stiffness_n_per_mm"] >= STIFF_N_PER_MM}
    assert hysteretic and stiff - hysteretic and set(truths) - hysteretic - stiff
    assert {(j.cell, j.start) for j in jobs if j.approach == "auto"} == {
        (c, s) for c in truths for s in ("probe", "cold")}
    assert {j.cell for j in jobs if j.approach == "direct"} == hysteretic
    order = [(j.start, j.approach) for j in jobs]
    assert order[: len(truths)] == [("probe", "auto")] * len(truths)
    designs = order[len(truths):len(truths) + 2 * len(hysteretic)]
    assert designs == ([("probe", "direction")] * len(hysteretic)
                       + [("probe", "direct")] * len(hysteretic))  # each design on every cell
    cold = [j.cell for j in jobs if j.start == "cold"]
    first_cold = len(hysteretic | stiff)
    assert set(cold[:first_cold]) == hysteretic | stiff
    config = tomllib.loads(next(j for j in jobs if j.approach == "direction" or j.start == "cold")
                           .config.read_text())
    assert config["run"]["stop_after_converged"] > 0
    for job in jobs[:3]:
        _fake_run(job.out, 2 if job.approach == "auto" else None, 0.5)
    found = collect(jobs, cells)
    assert [r.cell for r in found] == [j.cell for j in jobs[:3]]
    page, figure = tmp_path / "materials.md", tmp_path / "materials.png"
    write_figure(found, figure)
    write_page(found, page, figure, 40, 100, "python -m forcelearn.tools.results.materials")
    text = page.read_text()
    assert "| cell-01 | probe | auto |" in text and "start 'probe'" in text
