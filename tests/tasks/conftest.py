"""Shared fixtures of the task tests."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from forcelearn.site.session import CellSession

TruePeak = Callable[[CellSession], list[float]]


def _record_true_peak(session: CellSession) -> list[float]:
    """The largest true contact force the sponge exerts from now on, N (a one-item list)."""
    sponge = session.sponge
    assert sponge is not None
    peak = [0.0]
    original = sponge.contact_force_world_n

    def recorded(position_mm: np.ndarray) -> np.ndarray:
        force = original(position_mm)
        peak[0] = max(peak[0], float(np.linalg.norm(force)))
        return force

    sponge.contact_force_world_n = recorded  # type: ignore[method-assign]
    return peak


@pytest.fixture
def true_force_peak() -> TruePeak:
    """Call it with a session: the list it returns holds the session's peak true force (N)."""
    return _record_true_peak
