"""Bursts read one after another with no wait between: the twin starts each after the one before."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from forcelearn.drivers.jr3_can import driver as jr3_driver
from forcelearn.emulators.clock import SimClock
from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.records import read_records
from forcelearn.tools.fuzz.fault_campaign import cell_config
from forcelearn.tools.twin.arm import chained_offsets_s, command_s
from forcelearn.tools.twin.arrays import to_arrays


def test_the_probes_reads_at_contact_begin_when_the_read_before_ended(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each chained burst's offset from the shared recorded start is the driver's own, to 1 ms.

    The probe reads three bursts at each contact, all recorded at the end of the wait before
    them; taken at that start, the third was put about 40 ms early.
    """
    clocks: list[SimClock] = []
    made = SimClock.__init__

    def kept(self: SimClock, *args: Any, **kwargs: Any) -> None:
        made(self, *args, **kwargs)
        clocks.append(self)

    asked: list[float] = []
    read_many = jr3_driver.Jr3CanSensor.read_many

    def logged(self: Any, count: int, window: int = 1) -> Any:
        asked.append(clocks[-1].now_s)
        return read_many(self, count, window)

    monkeypatch.setattr(SimClock, "__init__", kept)
    monkeypatch.setattr(jr3_driver.Jr3CanSensor, "read_many", logged)
    config = cell_config("link+jr3", tmp_path, trials=1, steps=4, probe=True)
    run, checkpoint = run_state.prepare_run(config, tmp_path / "run", None, 0, resume=False)
    engine.execute(run, checkpoint)

    data = to_arrays(list(read_records(tmp_path / "run", probe=True)))
    offsets = chained_offsets_s(data)
    chained = offsets > 0
    assert chained.sum() >= 7  # at least one chain per probe point
    times = np.array(asked)
    for row, slot in zip(*np.nonzero(chained), strict=True):
        start = data.burst_start_s[row, slot]
        first = int(np.searchsorted(times, start - 1e-9))  # the chain's first read
        later = int(np.sum(chained[row, :slot + 1] & (data.burst_start_s[row, :slot + 1] == start)))
        truth = times[first + later] - times[first]
        assert truth > 0.02
        assert offsets[row, slot] == pytest.approx(truth, abs=0.001)
    # a move after a chain is commanded after all of it
    after = np.concatenate([np.zeros((data.trials, 1), bool), chained[:, :-1]], axis=1)
    moved = after & np.isfinite(data.move_mm) & (data.move_mm > 0)
    span = np.nan_to_num(data.burst_span_s)
    last = np.concatenate([np.zeros((data.trials, 1)), span[:, :-1]], axis=1)
    assert np.all(command_s(data)[moved] > (data.start_s + last)[moved] + 0.02)
