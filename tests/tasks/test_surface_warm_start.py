"""The learner's warm start from the probe (pure: made-up fits, no cell)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from forcelearn.errors import ConfigError
from forcelearn.learning import SRVLearner, SRVParams
from forcelearn.learning.exploration import sigma_of_prediction
from forcelearn.tasks.surface import SurfaceTaskSpec
from forcelearn.tasks.surface_fit import ContactFit, ProbeResult, ProbeSpec
from forcelearn.tasks.surface_map import choose_output_map
from forcelearn.tasks.surface_warm_start import (
    check_learner_start,
    relaxation_share,
    step_targets,
    warm_start,
)


def _probe(k: float, contacts: list[float], contact_std: float = 0.05) -> ProbeResult:
    """Fits at Z = 0, -25 ... -100 with one stiffness; two press rows 10 % early-high."""
    fits = [
        ContactFit(-25.0 * i, k, 0.02, y, contact_std, 0.1, 6) for i, y in enumerate(contacts)
    ]
    rows = [
        {"point": 0, "z_mm": 0.0, "y_mm": -3.0, "phase": "press", "early_force_n": 11.0,
         "force_n": 10.0, "cell_time_s": 0.0},
        {"point": 0, "z_mm": 0.0, "y_mm": -5.0, "phase": "press", "early_force_n": 22.0,
         "force_n": 20.0, "cell_time_s": 0.0},
    ]
    return ProbeResult(rows=rows, fits=fits, baselines_n=[0.0] * len(fits))  # type: ignore[list-item]


def _learner(task: SurfaceTaskSpec, output: object) -> SRVLearner:
    return SRVLearner(task.grid(), 1, SRVParams(extent=(3,)), rng=0, output=output)  # type: ignore[arg-type]


@pytest.mark.parametrize("follow", [False, True], ids=["constant-centre", "follows-surface"])
def test_the_learners_first_means_command_the_probes_path(follow: bool) -> None:
    """Acting on its means (no search), the warm learner commands the probe's target per step.

    The input before step k+1 is the travel k * 5 mm (what SurfaceTask gives);
    its command must be the Y where the fits give the desired force at that step's Z.
    """
    task = SurfaceTaskSpec()
    probe = _probe(2.0, [1.0, 2.5, 1.5, 0.0, 1.2])
    choice = choose_output_map(probe, task, ProbeSpec(), -60.0, follow=follow)
    output = choice.output(5.0)
    learner = _learner(task, output)
    cold = [float(learner.act(np.array([5.0 * k]), explore=False).output[0]) for k in range(20)]
    warm_start(learner, probe, task, output)
    commands = [float(learner.act(np.array([5.0 * k]), explore=False).output[0])
                for k in range(20)]
    path = probe.target_path_mm(task)
    assert commands == pytest.approx(list(path), abs=1e-9)
    if not follow:  # a constant centre's cold start does not (a path's centre is the path)
        assert not np.allclose(cold, path, atol=0.1)


@pytest.mark.parametrize("tare", [False, True], ids=["no-tare", "tare-each-trial"])
def test_the_warm_start_aims_where_the_drifted_sensor_reads_the_desired_force(tare: bool) -> None:
    """The probe's last free-space reading is the bias the task reads on top of the force.

    A sensor reading 0.6 N low in free space at the probe's end reads the
    desired force 0.6 N / k deeper; a task that tares before each trial does not.
    """
    k, drift = 2.0, -0.6
    task = SurfaceTaskSpec(tare_each_trial=tare)
    drifted = _probe(k, [1.0, 2.5, 1.5, 0.0, 1.2])
    drifted.baselines_n[-1] = drift
    targets, _ = step_targets(drifted, task)
    shift = 0.0 if tare else drift / k
    assert targets == pytest.approx(drifted.target_path_mm(task) + shift, abs=1e-9)


def test_a_target_beyond_the_range_is_held_at_its_end() -> None:
    """μ is clipped to the action range: the command sits at the range's end, not beyond."""
    task = SurfaceTaskSpec()
    probe = _probe(2.0, [1.0, 2.5, 1.5, 0.0, 1.2])
    choice = choose_output_map(probe, task, ProbeSpec(), -60.0)
    narrow = choice.output(5.0)
    narrow.max_offset_mm = 0.5
    learner = _learner(task, narrow)
    warm_start(learner, probe, task, narrow)
    limit = narrow.max_offset_mm / narrow.scale_mm
    assert np.all(np.abs(learner.weights) <= limit + 1e-12)
    assert np.isclose(np.abs(learner.weights), limit).any()


def test_the_search_width_is_what_the_probe_does_not_know() -> None:
    """r̂ = |(k σ_y, residual, relaxation)| / tolerance: a worse fit searches wider."""
    task = SurfaceTaskSpec()
    sure, unsure = _probe(2.0, [1.0] * 5, 0.05), _probe(2.0, [1.0] * 5, 2.0)
    _, r_sure = step_targets(sure, task)
    _, r_unsure = step_targets(unsure, task)
    force = task.desired_force_n
    sigma_y = math.hypot(0.05, force / 4.0 * 0.02)
    share = relaxation_share(sure)
    assert share == pytest.approx(0.1)
    expected = math.hypot(2.0 * sigma_y, 0.1, share * force) / task.tolerance
    assert r_sure == pytest.approx(np.full(20, expected))
    assert np.all(r_unsure > r_sure)
    choice = choose_output_map(unsure, task, ProbeSpec(), -60.0)
    output = choice.output(5.0)
    learner = _learner(task, output)
    warm_start(learner, unsure, task, output)
    params = learner.params
    assert learner.act(np.array([0.0])).sigma == pytest.approx(
        sigma_of_prediction(float(r_unsure[0]), params.sigma_min, params.sigma_max)
    )


def test_only_known_starts_are_accepted() -> None:
    """run.learner_start is "probe" or "cold"; anything else names the key."""
    assert check_learner_start("cold") == "cold"
    with pytest.raises(ConfigError, match=r"run\.learner_start"):
        check_learner_start("warm")
    with pytest.raises(ConfigError, match=r"run\.learner_start"):
        check_learner_start(1)
