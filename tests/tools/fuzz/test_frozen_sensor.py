"""A sensor repeating one reading (a frozen Net F/T: its sequence goes on) is not force."""

from __future__ import annotations

import random
from pathlib import Path

from forcelearn.tools.experiments.fault_recovery import read_events
from forcelearn.tools.fuzz.fault_campaign import cell_config, one_run
from forcelearn.tools.fuzz.fault_extra import ExtraInjector
from forcelearn.tools.fuzz.fault_free import MATERIALS

TICK = 120
"""A device call in the second trial's steps (of about 133)."""


FROZEN_CALLS = 6
"""How long it stays frozen, device calls (fault_extra --seed 60's case: unfrozen before the
trial's zero check, which then had nothing to find)."""


class Frozen(random.Random):
    """Draws a freeze of :data:`FROZEN_CALLS`."""

    def randint(self, a: int, b: int) -> int:
        """The freeze's length."""
        return FROZEN_CALLS


def test_a_frozen_reading_in_contact_is_suspect_and_never_used(tmp_path: Path) -> None:
    """Frozen for 6 calls in contact: SensorSuspect, the trial run again, no reading used off."""
    config = cell_config("link+netft", tmp_path, trials=2, steps=8, probe=False,
                         settings=MATERIALS["stiff8"])
    injector = ExtraInjector({TICK: [("sensor", "stuck")]}, Frozen(0))
    report = one_run("link+netft", config, tmp_path / "run", 60, 133, 0, 0, 1e9,
                     injector=injector)
    assert injector.fired and injector.fired[0].in_contact
    assert report.finished and not report.over_limit
    assert report.beyond_3sigma == 0  # before: a reading 9.95 N off the true force was used
    assert "SensorSuspect" in [e["error"] for e in read_events(tmp_path / "run")]
