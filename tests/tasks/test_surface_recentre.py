"""The output range re-centred on the learner's drift: commands kept, range moved, bounded."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.tasks.surface import RECENTRE_SHARE, SurfaceYOutput


def tracking_map(shift_range: tuple[float, float] = (-20.0, 10.0)) -> SurfaceYOutput:
    """A constant-centre map at y = -7 mm, 2 mm per unit, ±10 mm, following wear."""
    return SurfaceYOutput(-7.0, 2.0, 10.0, wear_stiffness_n_per_mm=2.0,
                          shift_range_mm=shift_range)


def commands(output: SurfaceYOutput, actions: np.ndarray) -> np.ndarray:
    """The Y command (mm) of each step k for action ``actions[k]``."""
    return np.array([output.command_at_step(float(a), k) for k, a in enumerate(actions)])


def test_a_drift_past_the_share_moves_the_centre_and_keeps_every_command() -> None:
    """A drift past half the half-range moves the centre; every command stays the same."""
    output = tracking_map()
    means = np.full(20, -3.0)  # -6 mm: beyond half of the 10 mm half-range
    means[::2] = -2.5
    before = commands(output, means)
    move = output.recentre_on(means)
    assert move == pytest.approx(-5.5)  # the mean drift, 2.75 units x 2 mm
    assert output.recentre_mm == pytest.approx(-5.5)
    assert output.shift_mm == 0.0  # the start press does not move
    np.testing.assert_allclose(commands(output, means), before)
    # the deep end moved with the learner: the old range stopped at -17 mm, the new at -22.5 mm
    assert tracking_map().command_at_step(-5.0, 0) == pytest.approx(-17.0)
    assert output.command_at_step(-5.0, 0) == pytest.approx(-7.0 - 5.5 - 10.0)


def test_a_small_drift_moves_nothing() -> None:
    """Under the share, neither the centre nor any μ moves."""
    output = tracking_map()
    means = np.full(20, 0.9 * RECENTRE_SHARE * 10.0 / 2.0)
    kept = means.copy()
    assert output.recentre_on(means) == 0.0
    np.testing.assert_array_equal(means, kept)


def test_the_whole_displacement_stays_in_the_allowed_range() -> None:
    """Wear shift plus re-centring never leave ``shift_range_mm``."""
    output = tracking_map(shift_range=(-4.0, 3.0))
    output.shift_mm = -1.5  # wear already followed
    means = np.full(20, -4.0)  # -8 mm of drift
    move = output.recentre_on(means)
    assert move == pytest.approx(-2.5)
    assert output.displacement_mm == pytest.approx(-4.0)
    np.testing.assert_allclose(means, -4.0 + 2.5 / 2.0)
    # wear tracking then cannot take the range deeper than allowed either
    output.wear_reference_n = 20.0
    output.track_wear(10.0)  # 10 N missing: 2.5 mm deeper wanted
    assert output.displacement_mm == pytest.approx(-4.0)


def test_a_map_that_does_not_follow_wear_is_never_recentred() -> None:
    """A configured or fallback map (no stiffness to track with) stays put."""
    output = SurfaceYOutput(-7.0, 2.0, 10.0)  # configured or fallback map
    means = np.full(20, -4.0)
    assert output.recentre_on(means) == 0.0
    assert output.displacement_mm == 0.0
