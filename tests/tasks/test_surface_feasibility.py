"""The run's own 'out of reach' estimate, on made-up trials of a known foam (pure)."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.tasks.surface_feasibility import assess, worn_stiffness

DESIRED_N = 24.5
BAND_N = 0.05 * DESIRED_N
CONTACT_Y = 2.0


def _trials(
    k: float, centres: np.ndarray, spread_mm: float, trials: int = 10, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Commands around ``centres`` (one per step) on a foam F = k (contact − y), no noise."""
    rng = np.random.default_rng(seed)
    y = centres + spread_mm * rng.standard_normal((trials, len(centres)))
    return y, k * (CONTACT_Y - y)


def _assess(y: np.ndarray, f: np.ndarray, bottom: float, allowed: float, k_probe: float):  # type: ignore[no-untyped-def]
    rows = len(y)
    return assess(
        y.tolist(), f.tolist(),
        [[bottom] * y.shape[1]] * rows, [[bottom + 20.0] * y.shape[1]] * rows,
        [CONTACT_Y] * y.shape[1], trial=rows - 1, desired_force_n=DESIRED_N, band_n=BAND_N,
        probe_stiffness_n_per_mm=k_probe, allowed_bottom_y_mm=allowed,
    )


def test_the_worn_stiffness_is_the_slope_within_steps() -> None:
    """Each step's own surface Y drops out: the pooled slope is the foam's k."""
    y, f = _trials(0.56, np.linspace(-30.0, -25.0, 20), 0.3)
    f += np.linspace(0.0, 5.0, 20)  # a different contact at every step
    assert worn_stiffness(y, f) == pytest.approx(0.56)
    assert worn_stiffness(np.full((10, 20), -30.0), np.full((10, 20), 20.0)) is None


def test_a_worn_foam_that_cannot_give_the_force_before_the_backing_is_named() -> None:
    """The issue's cell: 0.56 N/mm worn, 38 mm allowed: 24.5 N needs 43.8 mm; 'foam', figures."""
    bottom = CONTACT_Y - 38.0  # the range reaches the deepest allowed Y
    y, f = _trials(0.56, np.full(20, bottom + 0.2), 0.2)
    found = _assess(y, f, bottom, bottom, k_probe=0.8)
    assert found is not None and found.reason == "foam"
    assert found.worn_stiffness_n_per_mm == pytest.approx(0.56)
    assert found.stiffness_source == "run"
    assert found.needed_depth_mm == pytest.approx(DESIRED_N / 0.56)  # below the contact
    assert found.force_at_bottom_n == pytest.approx(0.56 * 38.0)
    assert found.allowed_depth_mm == pytest.approx(38.0, abs=0.01)
    text = found.text()
    figures = ("0.56 N/mm", "0.80", f"{found.needed_depth_mm:.1f} mm", "38.0 mm",
               "probe.max_depth_mm", "task.desired_force_n")
    for figure in figures:
        assert figure in text, figure


def test_a_range_too_shallow_for_a_reachable_force_is_the_ranges_fault() -> None:
    """The foam could give it above the allowed bottom, the range stops short: 'range'."""
    bottom_of_range = CONTACT_Y - 30.0
    y, f = _trials(0.7, np.full(20, bottom_of_range + 0.1), 0.2)
    found = _assess(y, f, bottom_of_range, CONTACT_Y - 38.0, k_probe=0.8)
    assert found is not None and found.reason == "range"
    assert "probe.wear_margin" in found.text()


def test_a_force_in_reach_is_not_flagged() -> None:
    """Commands inside the range, or at its end but in band: no finding."""
    bottom = CONTACT_Y - 38.0
    y, f = _trials(0.8, np.full(20, CONTACT_Y - DESIRED_N / 0.8), 0.2)
    assert _assess(y, f, bottom, bottom, k_probe=0.8) is None
    at_end_in_band = _trials(DESIRED_N / 38.0, np.full(20, bottom + 0.1), 0.01)
    assert _assess(*at_end_in_band, bottom, bottom, k_probe=0.8) is None


def test_without_spread_the_probes_stiffness_bounds_the_depth() -> None:
    """Commands held at the end (no spread): the probe's k, said so; still 'foam' when short."""
    bottom = CONTACT_Y - 38.0
    y = np.full((10, 20), bottom)
    f = 0.4 * (CONTACT_Y - y)  # 15.2 N of 24.5
    found = _assess(y, f, bottom, bottom, k_probe=0.5)
    assert found is not None and found.stiffness_source == "probe"
    assert found.reason == "foam"
    assert "at most the probe's" in found.text()
