"""The batched §4 simulation gives every seed exactly its single run."""

from dataclasses import replace

import numpy as np
import pytest

from forcelearn.emulators.physics.two_link_arm import ContourGeometry, TwoLinkContourCell
from forcelearn.emulators.physics.two_link_batch import TwoLinkContourCells
from forcelearn.errors import ConfigError
from forcelearn.learning import SRVParams
from forcelearn.tools.experiments.contour import ContourConfig, run_contour
from forcelearn.tools.experiments.contour_batch import run_contour_batch

TIMING = {"wall_s", "steps_per_s", "batch_size"}


def test_batched_runs_equal_single_runs_seed_by_seed() -> None:
    """Records and summaries (all but timing) match run_contour for mixed settings."""
    base = ContourConfig(trials=150)
    configs = [
        replace(base, seed=0),
        replace(base, seed=1, learner=SRVParams(gamma=0.8, extent=(3, 4))),
        replace(base, seed=2, learner=SRVParams(generalized_phase=False)),
        replace(base, seed=3, learner=SRVParams(sigma_min=0.05, initial_prediction=1.0)),
    ]
    summaries, result = run_contour_batch(configs)
    assert any(s["phase_switch_trial"] is not None for s in summaries)  # phases switch
    for config, summary, records in zip(configs, summaries, result.records, strict=True):
        single = run_contour(config)
        assert records == single.result.records
        expected = {k: v for k, v in single.summary.items() if k not in TIMING}
        assert {k: v for k, v in summary.items() if k not in TIMING} == expected


def test_cells_follow_the_single_cell_exactly_with_servo_lag() -> None:
    """Angles, tips and forces of each arm equal a single cell's under the same commands."""
    geometry = ContourGeometry(servo_lag=0.3)
    cells = TwoLinkContourCells(geometry, 3)
    singles = [TwoLinkContourCell(geometry) for _ in range(3)]
    rng = np.random.default_rng(0)
    arms = np.arange(3)
    for _ in range(50):
        command = cells.theta_deg + rng.normal(0.0, 0.5, (3, 2))
        reached = cells.move(arms, command)
        tip = cells.tip_m(arms)
        force = cells.force_n(tip)
        for b, single in enumerate(singles):
            assert single.move(*command[b].tolist()) == tuple(reached[b])
            assert single.tip_m() == tuple(tip[b])
            assert single.force_n() == force[b]


def test_a_batch_needs_one_task_geometry_and_budget() -> None:
    """Configs that cannot share a batch are refused with a hint."""
    with pytest.raises(ConfigError, match="one batch per group"):
        run_contour_batch([ContourConfig(trials=5), ContourConfig(trials=6)])
