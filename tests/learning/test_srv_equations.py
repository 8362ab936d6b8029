"""Eqs. (1)-(3) of the paper checked against values computed by hand."""

import numpy as np
import pytest

from forcelearn.errors import ConfigError
from forcelearn.learning import Action, BoxGrid, Dimension, Phase, SRVLearner, SRVParams


def small_learner(**overrides: object) -> SRVLearner:
    """A 2-D 20 x 30 grid, d = (2, 3), γ = 0.5, two outputs, V0 = 1, W0 = 0."""
    settings = {"initial_prediction": 1.0, **overrides}
    params = SRVParams(extent=(2, 3), gamma=0.5, **settings)  # type: ignore[arg-type]
    grid = BoxGrid([Dimension("u", 0.0, 20.0, 20), Dimension("v", 0.0, 30.0, 30)])
    return SRVLearner(grid, n_outputs=2, params=params, rng=1)


def crafted_action(box: tuple[int, int], r_hat: float, sigma: float, mu: list, a: list) -> Action:
    """An action with known r̂, σ, μ and a, as if drawn by act()."""
    return Action(box, r_hat, sigma, np.array(mu, float), np.array(a, float), np.array(a, float))


def test_eq1_moves_the_input_prediction_by_beta_times_error() -> None:
    """ΔV = β (r − r̂): r̂ = 1, r = 0.2, β = 0.5 gives V = 0.6; no other box moves."""
    learner = small_learner()
    learner.learn(crafted_action((10, 15), 1.0, 0.5, [0, 0], [0.3, -0.1]), 0.2)
    assert learner.predictions[10, 15] == pytest.approx(0.6)
    changed = np.argwhere(learner.predictions != 1.0)
    assert changed.tolist() == [[10, 15]]


def test_eq2_moves_the_input_box_by_normalised_noise() -> None:
    """ΔW = α (r̂ − r)(a − μ)/σ = 0.5 · 0.8 · (0.3, −0.1) / 0.5 = (0.24, −0.08)."""
    learner = small_learner()
    learner.learn(crafted_action((10, 15), 1.0, 0.5, [0, 0], [0.3, -0.1]), 0.2)
    np.testing.assert_allclose(learner.weights[10, 15], [0.24, -0.08], rtol=1e-12)


def test_eq3_moves_neighbours_by_gamma_power_without_sigma() -> None:
    """ΔW = γ^(|d̂1|+|d̂2|) α (r̂ − r)(a − μ): e.g. offset (1, −2) gets 0.5³ · 0.12."""
    learner = small_learner()
    learner.learn(crafted_action((10, 15), 1.0, 0.5, [0, 0], [0.3, -0.1]), 0.2)
    base = 0.5 * 0.8 * np.array([0.3, -0.1])  # α (r̂ − r)(a − μ)
    np.testing.assert_allclose(learner.weights[11, 13], 0.5**3 * base, rtol=1e-12)
    np.testing.assert_allclose(learner.weights[8, 18], 0.5**5 * base, rtol=1e-12)
    np.testing.assert_allclose(learner.weights[10, 16], 0.5 * base, rtol=1e-12)
    # just outside the extents: untouched
    assert not learner.weights[13, 15].any()
    assert not learner.weights[10, 19].any()


def test_worse_than_predicted_pushes_the_mean_away_from_the_action() -> None:
    """With r > r̂ (worse than predicted) μ moves opposite to a − μ, in box and neighbours."""
    learner = small_learner()
    learner.learn(crafted_action((10, 15), 0.2, 0.1, [0, 0], [0.3, 0.3]), 0.9)
    assert (learner.weights[10, 15] < 0).all()
    assert (learner.weights[9, 14] < 0).all()


def test_interior_update_touches_121_boxes_with_paper_extents() -> None:
    """d1 = d2 = 5 updates the 11 x 11 = 121 boxes of §4 in the grid's interior."""
    grid = BoxGrid([Dimension("t1", 30, 60, 100), Dimension("t2", -75, -15, 200)])
    learner = SRVLearner(grid, n_outputs=2, params=SRVParams(), rng=0)
    learner.learn(crafted_action((50, 100), 1.0, 0.5, [0, 0], [0.3, 0.2]), 0.1)
    touched = np.argwhere(np.any(learner.weights != 0.0, axis=-1))
    assert len(touched) == 121
    assert touched.min(axis=0).tolist() == [45, 95]
    assert touched.max(axis=0).tolist() == [55, 105]


@pytest.mark.parametrize(
    ("box", "count"), [((0, 0), 36), ((0, 100), 66), ((99, 199), 36), ((3, 100), 99)]
)
def test_edge_and_corner_updates_are_clipped(box: tuple[int, int], count: int) -> None:
    """At edges and corners only the boxes that exist are touched (6·6, 6·11, 9·11)."""
    grid = BoxGrid([Dimension("t1", 30, 60, 100), Dimension("t2", -75, -15, 200)])
    learner = SRVLearner(grid, n_outputs=2, params=SRVParams(), rng=0)
    learner.learn(crafted_action(box, 1.0, 0.5, [0, 0], [0.3, 0.2]), 0.1)
    assert np.count_nonzero(np.any(learner.weights != 0.0, axis=-1)) == count


def test_specialized_phase_updates_only_the_input_box_with_its_own_alpha() -> None:
    """After the switch eq. (3) is off and α is the specialized one (0.1)."""
    learner = small_learner(success_trials=1)
    learner.end_trial(success=True)
    assert learner.phase is Phase.SPECIALIZED
    learner.learn(crafted_action((10, 15), 1.0, 0.5, [0, 0], [0.3, -0.1]), 0.2)
    np.testing.assert_allclose(learner.weights[10, 15], 0.1 * 0.8 * np.array([0.3, -0.1]) / 0.5)
    assert np.count_nonzero(learner.weights) == 2
    assert learner.predictions[10, 15] == pytest.approx(1.0 + 0.5 * (0.2 - 1.0))


def test_one_dimensional_and_three_dimensional_grids_learn() -> None:
    """The neighbourhood rule works for any number of dimensions: 1-D and 3-D."""
    grid1 = BoxGrid([Dimension("y_mm", 0, 10, 10)])
    learner1 = SRVLearner(grid1, 1, SRVParams(extent=(2,), gamma=0.8), rng=0)
    learner1.learn(crafted_action((0,), 1.0, 0.5, [0], [0.5]), 0.0)  # type: ignore[arg-type]
    np.testing.assert_allclose(learner1.weights[:4, 0], [0.5, 0.8 * 0.25, 0.64 * 0.25, 0.0])
    grid3 = BoxGrid([Dimension(n, 0, 1, 5) for n in "abc"])
    learner3 = SRVLearner(grid3, 1, SRVParams(extent=(1, 1, 1), gamma=0.5), rng=0)
    learner3.learn(crafted_action((2, 2, 2), 1.0, 1.0, [0], [1.0]), 0.0)  # type: ignore[arg-type]
    assert np.count_nonzero(learner3.weights) == 27
    assert learner3.weights[1, 1, 1, 0] == pytest.approx(0.125 * 0.5)


def test_act_draws_around_the_mean_with_sigma_of_prediction() -> None:
    """A ~ N(μ, s(r̂)): empirical mean and std of a − μ match over many draws."""
    learner = small_learner(sigma_min=0.05, sigma_max=0.5)
    learner.weights[4, 4] = [1.0, -2.0]
    learner.predictions[4, 4] = 0.4  # s = 0.05 + 0.45 * 0.4 = 0.23
    draws = np.array([learner.act((4.5, 4.5)).action for _ in range(20_000)])
    np.testing.assert_allclose(draws.mean(axis=0), [1.0, -2.0], atol=0.01)
    np.testing.assert_allclose(draws.std(axis=0), [0.23, 0.23], rtol=0.03)
    step = learner.act((4.5, 4.5))
    assert step.sigma == pytest.approx(0.23)
    assert learner.act((4.5, 4.5), explore=False).action.tolist() == [1.0, -2.0]


def test_extent_must_match_the_grid() -> None:
    """One extent d_i per dimension, or a ConfigError that says so."""
    grid = BoxGrid([Dimension("y", 0, 1, 10)])
    with pytest.raises(ConfigError, match="one extent"):
        SRVLearner(grid, 1, SRVParams(extent=(5, 5)))


def test_non_finite_evaluation_is_rejected() -> None:
    """A NaN evaluation would poison every box it reaches: refuse it."""
    learner = small_learner()
    with pytest.raises(ValueError, match="finite"):
        learner.learn(learner.act((1.0, 1.0)), float("nan"))
