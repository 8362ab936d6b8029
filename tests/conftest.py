"""Fixtures shared by the whole suite."""

import pytest

REQUIRED_SUMMARY_KEYS = frozenset(
    {
        "task",
        "seed",
        "trials",
        "phase_switch_trial",
        "converged_trial",
        "final_force_rms_n",
        "final_mean_r",
        "steps",
        "wall_s",
        "steps_per_s",
    }
)
"""The summary.json fields every task's run must write (the issues' contract)."""


@pytest.fixture()
def required_summary_keys() -> frozenset[str]:
    """The fields every summary.json must hold."""
    return REQUIRED_SUMMARY_KEYS
