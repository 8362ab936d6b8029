"""An EGM link lost in contact for longer than the controller's CommTimeout is resumed from."""

from __future__ import annotations

import random
from pathlib import Path

from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.fault_recovery import read_events
from forcelearn.tools.fuzz.fault_campaign import cell_config, injecting
from forcelearn.tools.fuzz.fault_inject import Injector, Truth

STEP = ("step", 3)
LOST = 300
"""Controller datagrams lost: 1.2 s of 4 ms cycles, past the 1 s CommTimeout."""


class Long(random.Random):
    """Draws a long EGM datagram loss of ``LOST`` datagrams."""

    def random(self) -> float:
        """A long loss."""
        return 0.0

    def randint(self, a: int, b: int) -> int:
        """``LOST``."""
        return LOST


class AtStep(Injector):
    """One EGM link drop at the first device call of ``STEP``."""

    def __init__(self) -> None:
        super().__init__({}, Long())

    def _step(self) -> None:
        super()._step()
        if not self.fired and self.session.cell.stage == STEP:
            self._fire("robot", "link_drop")


def test_a_link_lost_past_the_comm_timeout_in_contact_retracts_and_resumes(
    tmp_path: Path,
) -> None:
    """The controller stops, re-opens its session; the run retracts, re-zeroes, goes on."""
    config = cell_config("egm+jr3", tmp_path, trials=1, steps=4, probe=False)
    injector, truths = AtStep(), list[Truth]()
    with injecting(injector, 1.0, truths):
        run, checkpoint = run_state.prepare_run(config, tmp_path / "run", None, 5, resume=False)
        engine.execute(run, checkpoint)  # ends normally: no RecoveryFailed
    assert injector.fired and injector.fired[0].in_contact
    events = read_events(tmp_path / "run")
    assert [(e["error"], e["action"]) for e in events] == [("GuidanceStopped", "resumed")]
    assert events[0]["retract_y_mm"] == config_retract_y(tmp_path / "run")
    assert len(run.result.records) == 1 and truths[0].zeros_in_contact == 0


def config_retract_y(out: Path) -> float:
    """The run's retract plane, mm."""
    return run_state.load_cell_config(out / run_state.CONFIG_COPY).task.retract_y_mm
