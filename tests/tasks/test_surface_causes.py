"""The end diagnosis names the physical cause, each on a cell built to produce it."""

from __future__ import annotations

import numpy as np
from foam_cells import FoamCell, foam

from forcelearn.tasks.surface import SurfaceTask, SurfaceTaskSpec, SurfaceYOutput
from forcelearn.tasks.surface_diagnosis import RunEvidence, StuckMonitor, diagnose
from forcelearn.tasks.surface_fit import ContactFit, ProbeResult
from forcelearn.trainer import CONVERGENCE_TOLERANCE, TrialRecord

TRIALS = 8
STEPS = 8


def _run(cell: FoamCell, desired_n: float, approach_mm: float, spread_mm: float
         ) -> tuple[list[TrialRecord], RunEvidence]:
    """A searching learner's trials: Y = −10 mm + N(0, spread) at each step, on ``cell``."""
    spec = SurfaceTaskSpec(desired_force_n=desired_n, tolerance_n=1e3, steps_per_trial=STEPS)
    task = SurfaceTask(cell, spec, 10.0, SurfaceYOutput(-10.0, 2.0, 15.0, approach_mm=approach_mm))
    rng = np.random.default_rng(3)
    records, commands, forces = [], [], []
    for index in range(TRIALS):
        task.reset()
        ys = list(-10.0 + spread_mm * rng.standard_normal(STEPS))
        read = [task.step(np.array([y])).force_n for y in ys]
        rms = float(np.sqrt(np.mean((np.array(read) - desired_n) ** 2)))
        records.append(TrialRecord(index, "specialized", STEPS, False, 0.1, rms, 0.0))
        commands.append(ys)
        forces.append(read)
    rms_curve = [r.force_rms_n for r in records]
    return records, RunEvidence(desired_n, commands, forces, rms_curve, approach_mm=approach_mm)


def _diagnosis(records: list[TrialRecord], evidence: RunEvidence) -> str:
    monitor = StuckMonitor(-10.0, 15.0, STEPS)
    verdict = diagnose(records, None, monitor, evidence.desired_force_n, evidence=evidence)
    return str(verdict["diagnosis"])


def test_a_hysteretic_foam_moved_straight_to_its_steps_names_both_branch_means() -> None:
    """Pressing in and easing off read differently: the cause is named with both means."""
    text = _diagnosis(*_run(FoamCell(foam(0.25)), 20.0, 0.0, 1.0))
    assert "hysteresis: steps that pressed in read" in text and "eased off" in text
    assert 'task.approach = "loading"' in text


def test_approached_from_the_loading_side_the_same_foam_shows_no_branch_gap() -> None:
    """The same foam read on one branch: no hysteresis named."""
    text = _diagnosis(*_run(FoamCell(foam(0.25)), 20.0, 2.0, 1.0))
    assert "hysteresis" not in text


def test_a_noisy_sensor_is_diagnosed_as_noise_against_the_band() -> None:
    """An elastic foam read with noise larger than the band: noise named with its figure."""
    desired = 20.0
    noisy = FoamCell(foam(0.0), noise_n=3.0 * CONVERGENCE_TOLERANCE * desired)
    text = _diagnosis(*_run(noisy, desired, 0.0, 0.5))
    assert "noise against the band" in text and "hysteresis" not in text


def test_a_band_below_the_surface_fits_resolution_is_diagnosed() -> None:
    """A stiff part whose position band is under the probe's standard error of the target Y."""
    records, evidence = _run(FoamCell(foam(0.0)), 20.0, 0.0, 0.05)
    fits = [ContactFit(-25.0 * i, 8.0, 0.05, 5.0, 0.4, 0.1, 6) for i in range(3)]
    probe = ProbeResult(fits=fits, baselines_n=[0.0, 0.0, 0.0])
    text = _diagnosis(records, RunEvidence(**{**evidence.__dict__, "probe": probe}))
    assert "below what the surface fit resolves" in text and "±0.125 mm" in text


def test_more_trials_are_advised_only_while_the_learning_curve_falls() -> None:
    """A falling curve: 'more trials may do'; a flat one: said to be flat, not that."""
    monitor = StuckMonitor(-10.0, 15.0, STEPS)
    falling = [TrialRecord(i, "specialized", STEPS, False, 0.1, 5.0 - 0.1 * i, 0.0)
               for i in range(40)]
    flat = [TrialRecord(i, "specialized", STEPS, False, 0.1, 3.0 + 0.01 * (i % 3), 0.0)
            for i in range(40)]
    for records, expected in ((falling, True), (flat, False)):
        evidence = RunEvidence(20.0, [], [], [r.force_rms_n for r in records])
        text = str(diagnose(records, None, monitor, 20.0, evidence=evidence)["diagnosis"])
        assert ("more trials (run.trials / --trials) may do" in text) is expected
        assert ("the learning curve is flat" in text) is not expected
