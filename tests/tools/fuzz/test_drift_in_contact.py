"""A steady drift of the sensor's zero near the force limit: the press guard keeps its headroom."""

from __future__ import annotations

import random
from pathlib import Path

from forcelearn.press_guard import DriftCheck, drift_rate_bound_n_per_s
from forcelearn.tools.fuzz.fault_campaign import cell_config, one_run
from forcelearn.tools.fuzz.fault_extra import ExtraInjector
from forcelearn.tools.fuzz.fault_free import MATERIALS

TICK = 64
"""The device call the drift starts at (fault_extra --seed 0's first run on the JR3: before the
fix its first session passed 60 N at 60.29 N, and a resumed one again)."""


def test_a_drift_under_a_checks_noise_stays_in_the_headroom(tmp_path: Path) -> None:
    """0.02 N per device call from the first trial on a cold 8 N/mm part at 5 N: never over 60 N."""
    config = cell_config("link+jr3", tmp_path, trials=2, steps=8, probe=False,
                         settings=MATERIALS["stiff8-small"])
    injector = ExtraInjector({TICK: [("sensor", "drift")]}, random.Random(0))
    report = one_run("link+jr3", config, tmp_path / "run", 0, 138, 0, 0, 1e9, injector=injector)
    assert injector.drifting
    assert report.over_limit == 0, report.max_contact_n  # the emulator's true force
    assert report.zeros_in_contact == 0


def test_the_rate_bound_covers_what_a_check_could_not_resolve() -> None:
    """A check that read less than its noise still bounds the drift by reading + noise."""
    check = DriftCheck(read_n=-0.28, noise_n=0.27, elapsed_s=3.4, zero_time_s=0.0)
    assert drift_rate_bound_n_per_s([check]) >= 0.28 / 3.4
    # a check a moment after another is combined with it (its noise over 0.1 s bounds nothing)
    soon = DriftCheck(read_n=0.01, noise_n=0.27, elapsed_s=0.1, zero_time_s=3.4)
    assert drift_rate_bound_n_per_s([check, soon]) < drift_rate_bound_n_per_s([soon])
    assert drift_rate_bound_n_per_s([]) == 0.0
