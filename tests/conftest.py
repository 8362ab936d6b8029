"""Fixtures shared by the whole suite, and the hypothesis profile."""

import pytest
from hypothesis import settings

from forcelearn.tasks.surface import FALLBACK_OFFSET_MM, FALLBACK_SCALE_MM, SurfaceTaskSpec

# No per-example deadline: hypothesis's default (200 ms) fails property tests on a busy
# host (seen at load average 20 on 2 cores); the example counts bound the work instead,
# and pytest-timeout catches a hang.
settings.register_profile("forcelearn", deadline=None)
settings.load_profile("forcelearn")

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


CONFIGURED_MAP_TOML = (
    f"[task]\noutput_centre_y_mm = {SurfaceTaskSpec().start_mm[1]}\n"
    f"output_scale_mm = {FALLBACK_SCALE_MM}\nmax_offset_mm = {FALLBACK_OFFSET_MM}\n"
)
"""The whole output map of the first delivery (start Y, 2 mm, 15 mm) in a config: the run
skips the surface probe (~4 s). For tests where the probe is not the point."""


@pytest.fixture()
def configured_map_toml() -> str:
    """A ``[task]`` table with the whole output map: a run with it does not probe."""
    return CONFIGURED_MAP_TOML
