"""The batched learner gives each member exactly what a single SRVLearner gives."""

from dataclasses import replace

import numpy as np
import pytest

from forcelearn.errors import ConfigError
from forcelearn.learning import BoxGrid, BoxRangeError, Dimension, SRVLearner, SRVParams
from forcelearn.learning.batched import NORMAL_BLOCK, BatchedSRVLearner

GRID = BoxGrid([Dimension("a", 0.0, 1.0, 12), Dimension("b", -1.0, 1.0, 9)])
PARAMS = [
    SRVParams(),
    SRVParams(gamma=0.7, extent=(2, 3), sigma_min=0.05),
    SRVParams(generalized_phase=False, alpha_specialized=0.5),
    SRVParams(extent=(0, 1), success_trials=2, initial_prediction=1.0, initial_mean=0.3),
]


def test_members_match_single_learners_step_for_step() -> None:
    """Random inputs, evaluations, acting subsets and phase switches: W, V, actions equal."""
    seeds = [3, 11, 5, 7]
    batch = BatchedSRVLearner(GRID, 2, PARAMS, seeds)
    singles = [SRVLearner(GRID, 2, p, rng=s) for p, s in zip(PARAMS, seeds, strict=True)]
    drive = np.random.default_rng(99)
    steps = (NORMAL_BLOCK // 2) + 300  # crosses a refill of the normal buffers
    for k in range(steps):
        members = np.flatnonzero(drive.uniform(size=4) < 0.8)
        if members.size == 0:
            continue
        x = np.column_stack([drive.uniform(0, 1, members.size), drive.uniform(-1, 1, members.size)])
        r = drive.uniform(0.0, 1.2, members.size)
        step = batch.act(members, x)
        batch.learn(step, r)
        for j, b in enumerate(members.tolist()):
            single = singles[b].act(x[j])
            assert np.array_equal(single.action, step.action[j])
            assert np.array_equal(single.output, step.output[j])
            singles[b].learn(single, float(r[j]))
        if k % 17 == 0:
            for b in range(4):
                success = bool(drive.uniform() < 0.7)
                assert batch.end_trial(b, success) == singles[b].end_trial(success)
    assert any(s.schedule.switch_trial is not None for s in singles)  # phase switches happened
    for b, single in enumerate(singles):
        assert batch.phase(b) is single.phase
        assert np.array_equal(batch.weights[b], single.weights)
        assert np.array_equal(batch.predictions[b], single.predictions)
        assert np.array_equal(batch.member_weights(b), single.weights)
        assert np.array_equal(batch.member_predictions(b), single.predictions)
        member = batch.member(b)
        assert np.array_equal(member.weights, single.weights)
        assert np.array_equal(member.predictions, single.predictions)
        assert member.schedule == single.schedule


def test_greedy_act_draws_nothing_and_returns_the_mean() -> None:
    """explore=False gives μ and leaves the random streams where they were."""
    batch = BatchedSRVLearner(GRID, 2, PARAMS[:2], [0, 1])
    step = batch.act(np.array([0, 1]), np.array([[0.5, 0.0], [0.1, 0.2]]), explore=False)
    assert np.array_equal(step.action, step.mean)
    assert batch._used.tolist() == [NORMAL_BLOCK, NORMAL_BLOCK]


def test_out_of_range_input_names_the_dimension() -> None:
    """An input outside the grid is a BoxRangeError, as for the single learner."""
    batch = BatchedSRVLearner(GRID, 1, PARAMS[:1], [0])
    with pytest.raises(BoxRangeError, match=r"b=1\.5"):
        batch.act(np.array([0]), np.array([[0.5, 1.5]]))


def test_params_and_seeds_must_pair_up() -> None:
    """One SRVParams per seed, and extents that fit the grid."""
    with pytest.raises(ConfigError, match="one SRVParams per seed"):
        BatchedSRVLearner(GRID, 1, PARAMS[:2], [0])
    with pytest.raises(ConfigError, match="extent"):
        BatchedSRVLearner(GRID, 1, [replace(PARAMS[0], extent=(1, 1, 1))], [0])
