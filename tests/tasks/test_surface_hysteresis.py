"""A hysteretic foam: the probe's fit of h and its depth, and the task's reading branch."""

from __future__ import annotations

import numpy as np
import pytest
from foam_cells import FoamCell, foam

from forcelearn.devices import Pose
from forcelearn.tasks.surface import SurfaceTask, SurfaceTaskSpec, SurfaceYOutput
from forcelearn.tasks.surface_fit import ProbeResult, ProbeRow
from forcelearn.tasks.surface_hysteresis import NOT_FITTED, fit_hysteresis
from forcelearn.tasks.surface_map import APPROACH_DEPTHS, approach_depth_mm


def _probe_rows(cell: FoamCell, z_mm: float, eases: tuple[float, ...]) -> list[ProbeRow]:
    """Press in from the surface in 1.5 mm steps, then ease off from the deepest: as the probe."""
    rows: list[ProbeRow] = []

    def read(y: float, phase: str) -> None:
        cell.move_in_steps(Pose(900.0, y, z_mm), 10.0)
        force = cell.measure_force_n()
        rows.append({"point": 0, "z_mm": z_mm, "y_mm": y, "phase": phase,
                     "early_force_n": force, "force_n": force, "cell_time_s": 0.0})

    cell.move_in_steps(Pose(900.0, 15.0, z_mm), 10.0)
    deepest = -9.0
    for y in np.arange(-0.5, deepest - 0.1, -1.5):
        read(float(y), "press")
    for ease in eases:
        read(float(y) + ease, "ease")
    return rows


@pytest.mark.parametrize("loss", [0.1, 0.25])
def test_the_probe_fit_recovers_a_known_hysteresis_and_depth(loss: float) -> None:
    """Press-in and ease-off readings of the emulator's foam give back h and d_h."""
    cell = FoamCell(foam(loss, depth_mm=0.6), noise_n=0.05)
    rows = _probe_rows(cell, 0.0, (0.25, 0.5, 1.0, 2.0, 4.0))
    fit = ProbeResult(rows=rows, baselines_n=[0.0, 0.05, -0.05]).hysteresis()
    assert fit.resolved
    assert fit.loss == pytest.approx(loss, abs=3 * fit.loss_std + 0.01)
    assert fit.depth_mm == pytest.approx(0.6, abs=3 * fit.depth_std + 0.05)
    assert fit.gap_n > 0 and "hysteresis h =" in fit.describe()


def test_a_fit_that_cannot_tell_hysteresis_from_noise_says_so() -> None:
    """On an elastic foam, noisy readings give an h within its errors of 0: not resolved."""
    cell = FoamCell(foam(0.0), noise_n=0.3)
    rows = _probe_rows(cell, 0.0, (0.25, 0.5, 1.0, 2.0, 4.0))
    fit = ProbeResult(rows=rows, baselines_n=[0.0, 0.3, -0.3]).hysteresis()
    assert not fit.resolved and "not resolved" in fit.describe()
    assert fit_hysteresis(np.array([1.0]), np.array([1.0]), np.array([1.0]), 0.1) == NOT_FITTED


def test_auto_approaches_from_the_loading_side_only_on_a_resolved_hysteresis() -> None:
    """task.approach: "auto" follows the fit, "loading" always, "direct" never."""
    cell = FoamCell(foam(0.2))
    fit = ProbeResult(rows=_probe_rows(cell, 0.0, (0.25, 0.5, 1.0, 2.0, 4.0)),
                      baselines_n=[0.0, 0.02]).hysteresis()
    auto = approach_depth_mm(SurfaceTaskSpec(), fit)
    assert auto == pytest.approx(APPROACH_DEPTHS * (fit.depth_mm + 2 * fit.depth_std))
    assert approach_depth_mm(SurfaceTaskSpec(), NOT_FITTED) == 0.0
    assert approach_depth_mm(SurfaceTaskSpec(approach="loading"), NOT_FITTED) > 0.0
    assert approach_depth_mm(SurfaceTaskSpec(approach="direct"), fit) == 0.0


def _force_after(previous_y_mm: float, approach_mm: float) -> float:
    """The force the task reads at step 2 (Y = −10 mm) after step 1 went to ``previous_y_mm``."""
    cell = FoamCell(foam(0.25))
    output = SurfaceYOutput(-10.0, 2.0, 15.0, approach_mm=approach_mm)
    wide = SurfaceTaskSpec(tolerance_n=40.0)  # no step fails (a failure retracts)
    task = SurfaceTask(cell, wide, 10.0, output)
    task.reset()
    assert not task.step(np.array([previous_y_mm])).failed
    return task.step(np.array([-10.0])).force_n


def test_the_task_reads_one_branch_whichever_way_the_previous_step_moved() -> None:
    """Approached from the loading side, a step reads the same force from above or below.

    Moved straight there, the same step reads the foam's loading branch after a
    step from above and its unloading branch after one from below.
    """
    direct = _force_after(-7.0, 0.0) - _force_after(-13.0, 0.0)
    loading = _force_after(-7.0, 2.0) - _force_after(-13.0, 2.0)
    reference = _force_after(-7.0, 2.0)
    assert direct > 0.1 * reference  # the branches differ by ~2h of the force
    assert abs(loading) < 0.01 * reference
