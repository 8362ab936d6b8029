"""Counts <-> N and N*m: one conversion per side of the JR3 wire, each the other's inverse."""

from __future__ import annotations

import numpy as np

from forcelearn.protocols.jr3_can.scaling import (
    COUNTS_PER_FULL_SCALE,
    INT16_MAX,
    INT16_MIN,
    counts_to_wrench,
    to_count,
    wrench_to_counts,
)

FULL_SCALES = np.array([110.0, 110.0, 220.0, 5.5, 5.5, 5.5])


def test_counts_round_trip_within_half_a_count() -> None:
    """The emulator's counts read back by the driver's conversion: within half a count."""
    rng = np.random.default_rng(0)
    for wrench in rng.uniform(-1.5, 1.5, (200, 6)) * FULL_SCALES:
        back = counts_to_wrench(wrench_to_counts(wrench, FULL_SCALES), FULL_SCALES)
        assert np.all(np.abs(back - wrench) <= 0.5 * FULL_SCALES / COUNTS_PER_FULL_SCALE)


def test_counts_are_rounded_half_to_even_and_clipped_to_int16() -> None:
    """Half a count rounds to even (as numpy); beyond the int16 range the count saturates."""
    assert [to_count(v) for v in (0.5, 1.5, -2.5, 2.49)] == [0, 2, -2, 2]
    assert to_count(1e9) == INT16_MAX and to_count(-1e9) == INT16_MIN
    assert wrench_to_counts(3 * FULL_SCALES, FULL_SCALES).tolist() == [INT16_MAX] * 6
