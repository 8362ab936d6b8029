"""A resumed Net F/T cell restores its state after what the driver sent has taken effect.

The driver's "set bias" on opening needs no answer, so the emulator's thread
may handle it after the session has restored the checkpoint, and then the
bias it computes overwrites the restored one: on a loaded host, a resumed run
read other forces than the straight run (the host's speed must never change a result).
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import pytest

from forcelearn.emulators.netft.sensor_model import NetFtSensorModel
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _state_of(session: CellSession) -> dict[str, Any]:
    assert session.sensor_emulator is not None
    return json.loads(json.dumps(session.emulator_state()["netft"]))


def test_a_slow_set_bias_takes_effect_before_the_restore(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The emulator's thread handles the bias 0.3 s late: the restored state still wins."""
    config = load_cell_config(EXAMPLES / "netft-cell.toml")
    with CellSession(config, seed=4) as first:
        assert first.cell is not None
        first.cell.measure_force_n()  # the model's generator and biases move on
        saved = first.emulator_state()
    original = NetFtSensorModel.set_software_bias
    slowed = threading.Event()

    def slow_set_bias(self: NetFtSensorModel, true_wrench: Any) -> None:
        slowed.wait(0.3)  # the host is busy
        original(self, true_wrench)

    monkeypatch.setattr(NetFtSensorModel, "set_software_bias", slow_set_bias)
    with CellSession(config, seed=4) as second:
        second.load_emulator_state(saved)
        slowed.wait(0.6)  # a bias handled late would have landed by now
        assert _state_of(second) == json.loads(json.dumps(saved["netft"]))
