"""A trial the run voided after a fault still wore the foam: the twin counts its passes."""

from __future__ import annotations

import json
import random
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge_law import SpongeParams
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.site.config import load_cell_config
from forcelearn.tasks.bias_watch import MARGIN_N
from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.fault_recovery import VOIDED_FILE
from forcelearn.tools.experiments.records import read_records, step_to_json
from forcelearn.tools.fuzz.fault_campaign import cell_config, injecting
from forcelearn.tools.fuzz.fault_inject import Injector
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.pass_count import surface_passes
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.source import read_run_records, voided_moves, with_voided_moves


class JumpInContact(Injector):
    """The sensor's bias jumps once at trial 0's third control step, under the watch's margin.

    The watch cannot tell it from the foam; the trial's zero check finds the zero moved
    and voids the trial after it has pressed the foam, and the trial runs again.
    """

    def __init__(self) -> None:
        super().__init__({}, random.Random(0))

    def _step(self) -> None:
        super()._step()
        if not self.fired and self.session.cell.stage == ("step", 3):
            self.rng = _UnderTheMargin()
            self._fire("sensor", "bias_jump")


class _UnderTheMargin(random.Random):
    def uniform(self, a: float, b: float) -> float:
        return 0.6 * MARGIN_N

    def choice(self, seq: Any) -> Any:
        return seq[-1]


def _burst_counts(counted: np.ndarray, starts: np.ndarray, log: list[tuple[float, int]]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The twin's count and the emulated sponge's at each burst's start."""
    times = np.array([t for t, _ in log])
    passes = np.array([n for _, n in log])
    at = np.searchsorted(times, starts, side="right") - 1
    return counted, np.where(at >= 0, passes[np.maximum(at, 0)], 0)


def test_the_passes_of_a_voided_trial_are_counted_as_the_emulated_sponge_counts_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At every burst the twin's count at the truth equals the sponge's own count.

    Before, the voided trial's moves were not read: its press was never seen entering the
    foam, and every burst from the fault on was counted one pass short.
    """
    log: list[tuple[float, int]] = []
    advance = CellPhysics.advance_to

    def logged(self: CellPhysics, t_s: float | None = None) -> None:
        advance(self, t_s)
        passes = getattr(self.environment, "passes", None)
        if passes is not None and (not log or log[-1][1] != passes):
            log.append((self.clock.now_s if t_s is None else t_s, passes))

    monkeypatch.setattr(CellPhysics, "advance_to", logged)
    folder = tmp_path / "run"
    config = cell_config("link+jr3", tmp_path, trials=2, steps=4, probe=False)
    with injecting(JumpInContact(), 1.0, []):
        run, checkpoint = run_state.prepare_run(config, folder, None, 5, resume=False)
        engine.execute(run, checkpoint)
    voided = [json.loads(line) for line in (folder / VOIDED_FILE).read_text().splitlines()]
    assert [v["trial"] for v in voided] == [0]
    assert "step" in {s["stage"] for s in voided[0]["steps"]}  # it pressed before its check

    truth = SpongeParams(**vars(load_cell_config(config).emulator.sponge))
    arm = base_arm()
    counts = []
    for records in (read_run_records(folder), list(read_records(folder, probe=True))):
        data = to_arrays(records)
        counted = surface_passes([data], truth, arm)[0]
        bursts = data.has_burst
        counts.append(_burst_counts(counted.passes[bursts], data.burst_start_s[bursts], log))
    (twin, sponge), (unvoided, _) = counts
    assert np.array_equal(twin, sponge)
    assert (unvoided < sponge).any()  # the records alone: passes short from the fault on


def _step(trial: int, start_s: float) -> StepRecord:
    move = MoveRecord((900.0, -1.0, 0.0), (900.0, -1.0, 0.0), start_s, start_s + 0.2,
                      start_s + 0.2)
    return StepRecord(trial, 1, "step", move,
                      BurstRecord(1.0, 0.1, 1.0, 1.0, 4, start_s + 0.3, 0.01, 1.0, None))


def test_voided_moves_join_the_trial_run_again_in_time_order_without_their_bursts(
    tmp_path: Path,
) -> None:
    """Into the first recorded trial at or after theirs; after the last recorded one: left out."""
    records = [TrialRecords(0, [_step(0, 1.0)], []), TrialRecords(2, [_step(2, 10.0)], [])]
    path = tmp_path / VOIDED_FILE
    lines = [{"trial": 0, "steps": [_step(0, 0.5)]}, {"trial": 1, "steps": [_step(1, 5.0)]},
             {"trial": 3, "steps": [_step(3, 20.0)]}]
    path.write_text("".join(json.dumps({"trial": line["trial"], "error": "ZeroMoved", "tares": [],
                                        "steps": [step_to_json(s) for s in line["steps"]]})
                            + "\n" for line in lines))
    voided = voided_moves(path)
    assert [s.burst for s in voided] == [None] * 3  # its readings are never used
    merged = with_voided_moves(records, voided)
    assert [[s.move.start_s for s in t.steps] for t in merged] == [[0.5, 1.0], [5.0, 10.0]]
    assert [s.trial for t in merged for s in t.steps] == [0, 0, 2, 2]
    assert [s.burst is None for t in merged for s in t.steps] == [True, False, True, False]
    assert voided_moves(tmp_path / "absent.jsonl") == []
