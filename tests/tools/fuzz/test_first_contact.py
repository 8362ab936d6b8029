"""A bias step at a session's first contact is found before the trial presses on it.

The session's first press has no earlier trusted one to be compared with: a bias step
landing as it meets the part (read as less force than there is) went unseen until the
trial's end, its zero check voiding what every step had read on the moved zero (each step
pressing deeper by the step's size). The first press is now made twice, from a zero
checked in free space before each, so the step is found before any step of the trial.
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any
from unittest import mock

from forcelearn.tools.experiments.fault_recovery import read_events
from forcelearn.tools.fuzz.fault_campaign import cell_config, one_run
from forcelearn.tools.fuzz.fault_free import MATERIALS
from forcelearn.tools.fuzz.fault_inject import Injector, Truth

JUMP_N = 8.0
TOLERANCE_N = 1.0


class Sized(random.Random):
    """Draws a bias jump of :data:`JUMP_N` upwards (read as less normal force)."""

    def uniform(self, a: float, b: float) -> float:
        """The jump's size."""
        return JUMP_N

    def choice(self, seq: Any) -> Any:
        """Upwards."""
        return seq[-1]


class AtFirstContact(Injector):
    """One bias jump as the first trial's start press first meets the part (past the step)."""

    def __init__(self) -> None:
        super().__init__({}, Sized(0))

    def _step(self) -> None:
        super()._step()
        assert self.truth is not None
        if (not self.fired and self.session.cell.stage == ("approach", 0)
                and self.truth.contact_n() > JUMP_N + 2.0):  # no pull: it reads as contact
            self._fire("sensor", "bias_jump")


def test_a_bias_step_at_the_first_contact_is_found_before_any_step_reads_it(
        tmp_path: Path) -> None:
    """No step of the trial is read on the moved zero; the trial runs again and completes."""
    config = cell_config("link+jr3", tmp_path, trials=1, steps=4, probe=False,
                         settings=MATERIALS["stiff8"])
    off_steps: list[tuple[str, int]] = []
    judge = Truth.judge_reading

    def judged(truth: Truth, reading_n: float, last_fault: str) -> None:
        before = len(truth._pending)
        judge(truth, reading_n, last_fault)
        stage = truth.session.cell.stage
        if stage[0] == "step" and len(truth._pending) > before and truth._pending[-1][1]:
            off_steps.append(stage)

    injector = AtFirstContact()
    with mock.patch.object(Truth, "judge_reading", judged):
        report = one_run("link+jr3", config, tmp_path / "run", 0, 100, 0, 0, TOLERANCE_N,
                         injector=injector)
    assert injector.fired and injector.fired[0].in_contact
    assert report.finished and not report.over_limit and report.zeros_in_contact == 0
    assert off_steps == []  # on main: every step of the trial, voided only at its end
    assert [e["error"] for e in read_events(tmp_path / "run")] in (["ZeroMoved"],
                                                                   ["SensorSuspect"])
