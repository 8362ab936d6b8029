"""The campaign's Net F/T ``corrupt`` fault reaches the driver, which refuses the damage."""

from __future__ import annotations

import random
from pathlib import Path

from forcelearn.tools.fuzz.fault_campaign import cell_config, one_run
from forcelearn.tools.fuzz.fault_inject import Injector

TICK = 20
"""A device call in the first trial's presses."""


def test_damaged_datagrams_arrive_are_refused_and_the_run_recovers(tmp_path: Path) -> None:
    """Damage is counted by the driver (rejected or a status error), never used as force."""
    config = cell_config("link+netft", tmp_path, trials=1, steps=4, probe=False)
    injector = Injector({TICK: [("sensor", "corrupt")]}, random.Random(3))
    report = one_run("link+netft", config, tmp_path / "run", 0, 100, 0, 0, 1e9,
                     injector=injector)
    stats = injector.session.sensor.stats
    assert sum(stats.rejected.values()) + stats.status_errors > 0  # the damage arrived
    assert report.finished and report.beyond_3sigma == 0 and not report.over_limit
