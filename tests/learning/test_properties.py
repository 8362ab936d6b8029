"""Hypothesis properties of the update: locality and the input box's exact change."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.learning import Action, BoxGrid, Dimension, SRVLearner, SRVParams


@st.composite
def update_cases(draw: st.DrawFn) -> tuple:
    """A random grid (1-3 dims), extents, γ, a box in it, and an action with its evaluation."""
    ndim = draw(st.integers(1, 3))
    parts = [draw(st.integers(1, 12)) for _ in range(ndim)]
    extent = tuple(draw(st.integers(0, 4)) for _ in range(ndim))
    gamma = draw(st.floats(0.05, 0.95))
    box = tuple(draw(st.integers(0, p - 1)) for p in parts)
    n_out = draw(st.integers(1, 3))
    finite = st.floats(-2.0, 2.0, allow_nan=False)
    mu = np.array([draw(finite) for _ in range(n_out)])
    a = np.array([draw(finite) for _ in range(n_out)])
    r_hat = draw(st.floats(0.0, 1.5))
    sigma = draw(st.floats(0.01, 1.0))
    r = draw(st.floats(0.0, 3.0))
    specialized = draw(st.booleans())
    return parts, extent, gamma, box, mu, a, r_hat, sigma, r, specialized


@settings(max_examples=200, deadline=None)
@given(update_cases())
def test_update_stays_within_extents_and_input_box_follows_eq2(case: tuple) -> None:
    """No box beyond the extents moves; the input box moves by exactly eq. (2)."""
    parts, extent, gamma, box, mu, a, r_hat, sigma, r, specialized = case
    grid = BoxGrid([Dimension(f"x{i}", 0.0, 1.0, p) for i, p in enumerate(parts)])
    params = SRVParams(extent=extent, gamma=gamma, success_trials=1)
    learner = SRVLearner(grid, len(mu), params, rng=0)
    learner.weights[...] = mu  # every box starts at μ, so changes are easy to read
    if specialized:
        learner.end_trial(True)
    alpha = params.alpha(learner.phase)
    before = learner.weights.copy()
    learner.learn(Action(box, r_hat, sigma, mu.copy(), a, a), r)
    change = learner.weights - before
    np.testing.assert_allclose(
        change[box], alpha * (r_hat - r) * (a - mu) / sigma, rtol=1e-9, atol=1e-12
    )
    offsets = np.abs(np.indices(grid.shape) - np.array(box).reshape(-1, *[1] * len(parts)))
    outside = np.any(offsets > np.array(extent).reshape(-1, *[1] * len(parts)), axis=0)
    assert not change[outside].any()
    if specialized:
        others = np.ones(grid.shape, bool)
        others[box] = False
        assert not change[others].any()
    else:
        expected = (gamma ** offsets.sum(axis=0))[..., None] * alpha * (r_hat - r) * (a - mu)
        inside = ~outside
        inside[box] = False
        np.testing.assert_allclose(change[inside], expected[inside], rtol=1e-9, atol=1e-12)
