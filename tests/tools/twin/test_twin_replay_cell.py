"""``forcelearn replay`` drives the twin's wire-level emulated cell."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from forcelearn.drivers.computer_link.config import LinkConfig
from forcelearn.site.config import load_cell_config
from forcelearn.tools.cli import main
from forcelearn.tools.twin.replay import replay
from forcelearn.tools.twin.replay_cell import ReplayRefused
from forcelearn.tools.twin.source import read_runs


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2-trial run of the default emulated cell (probe included)."""
    out = tmp_path_factory.mktemp("run") / "run"
    assert main(["run", "--trials", "2", "--seed", "0", "--out", str(out),
                 "--no-progress"]) == 0
    return out


def test_replay_on_its_own_config_reproduces_the_recorded_force(short_run: Path) -> None:
    """The recorded commands on the same emulated cell read the recorded force again."""
    source = read_runs([short_run])
    result = replay(source.records, load_cell_config(None), "cell", seed=0)
    data = result.data
    use = data.has_burst & np.isfinite(result.predicted)
    assert use.sum() >= 0.95 * data.has_burst.sum()  # every burst was read again
    error = (result.predicted - data.mean_n)[use]
    # the run's seed: the same sensor noise and bias drift, read again after the same moves
    scatter = np.sqrt(2.0) * np.nanmax(data.std_n[use] / np.sqrt(data.count[use]))
    assert np.sqrt(np.mean(error**2)) < 3 * scatter
    assert np.nanmax(np.abs(data.mean_n[use])) > 5.0  # the run pressed on the sponge


def test_replay_refuses_a_real_robot(short_run: Path) -> None:
    """A config that names a real device is refused before anything opens."""
    real = dataclasses.replace(load_cell_config(None), robot=LinkConfig(url="/dev/ttyS0"))
    with pytest.raises(ReplayRefused, match="real robot"):
        replay(read_runs([short_run]).records, real, "cell")


def test_unknown_model_is_a_value_error(short_run: Path) -> None:
    """Only cell and forward."""
    with pytest.raises(ValueError, match="model"):
        replay(read_runs([short_run]).records, load_cell_config(None), "guess")
