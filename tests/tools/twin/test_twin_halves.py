"""The force halves' check counts only their disagreement beyond each half's own sigma.

On the default cell's run (linear foam, seed 0) the high-force half alone trades the
contact against the stiffness: the halves' refits differ by about their own sigmas, and
half the gap (0.166 mm) was reported as the contact's sigma of a law that holds.
"""

from __future__ import annotations

import numpy as np

from forcelearn.tools.twin.problem import halves_excess


def test_a_gap_the_halves_own_sigmas_explain_adds_nothing() -> None:
    """Two ill-conditioned halves that agree within their sigmas: no model error."""
    excess = halves_excess(np.array([0.05, 2.0]), np.array([0.38, 2.0]),
                           np.array([0.2, 0.01]), np.array([0.3, 0.01]))
    assert np.all(excess == 0.0)


def test_a_gap_far_beyond_the_own_sigmas_is_kept() -> None:
    """A law that does not hold (halves 1.5 mm apart, each known to 0.02 mm): about gap/2."""
    gap = 1.5
    excess = halves_excess(np.array([0.0]), np.array([gap]), np.array([0.02]),
                           np.array([0.02]))
    assert gap / 2 * 0.99 < excess[0] <= gap / 2


def test_an_unknown_own_sigma_keeps_the_whole_gap() -> None:
    """A half with no refit step (infinite sigma) cannot excuse the gap."""
    excess = halves_excess(np.array([0.0]), np.array([0.4]), np.array([np.inf]),
                           np.array([0.1]))
    assert excess[0] == 0.2


def test_the_excess_grows_with_the_gap() -> None:
    """The same halves' sigmas: a larger gap never gives a smaller excess."""
    gaps = np.linspace(0.0, 2.0, 21)
    excess = halves_excess(np.zeros_like(gaps), gaps, np.full_like(gaps, 0.2),
                           np.full_like(gaps, 0.3))
    assert np.all(np.diff(excess) >= 0.0)
    assert excess[-1] > 0.0
