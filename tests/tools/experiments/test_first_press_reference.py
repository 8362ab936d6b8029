"""The first press with nothing trusted to compare it with is made twice (issue 38).

After a tare of the sensor (``[task] tare_each_trial``, a re-zero after a fault) and after
``--resume`` on a real cell (a process restart: unknown time passed, the sensor may have
rebooted or drifted), the next first press is made twice from zeros checked in free space.
An emulated resume restores the emulated sensor with the zero its last session had, and the
press guard's reference with it: it goes on as the uninterrupted run did (bit-identical).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import pytest

from forcelearn.site.session import CellSession
from forcelearn.tools.cli import main
from forcelearn.tools.experiments.fault_recovery import RunRecovery
from forcelearn.tools.fuzz.fault_campaign import cell_config


@pytest.fixture
def presses() -> Iterator[list[int]]:
    """The presses each trial's first press took (2: made twice), in order."""
    made: list[int] = []
    press_in = RunRecovery.press_in

    def counted(recovery: RunRecovery, press: Callable[[], float]) -> float:
        count = [0]

        def counting() -> float:
            count[0] += 1
            return press()

        try:
            return press_in(recovery, counting)
        finally:
            made.append(count[0])

    with mock.patch.object(RunRecovery, "press_in", counted):
        yield made


def _run(config: Path, out: Path, trials: int, resume: bool = False) -> None:
    args = (["run", "--resume", str(out)] if resume
            else ["run", "--config", str(config), "--seed", "3", "--out", str(out)])
    assert main([*args, "--trials", str(trials), "--no-progress"]) == 0


def test_a_tare_each_trial_makes_the_next_first_press_twice(
        tmp_path: Path, presses: list[int]) -> None:
    """Every trial tares: no trial's first press has a reference on the new zero."""
    config = cell_config("link+jr3", tmp_path, 3, 2, False, ("task.tare_each_trial=true",))
    _run(config, tmp_path / "run", 3)
    assert presses == [2, 2, 2]  # before: [2, 1, 1], the tare kept the first trial's reference


def test_without_a_tare_only_the_session_s_first_press_is_made_twice(
        tmp_path: Path, presses: list[int]) -> None:
    """The zero checks' software zeros keep the reference (a check is not a new zero)."""
    config = cell_config("link+jr3", tmp_path, 3, 2, False)
    _run(config, tmp_path / "run", 3)
    assert presses == [2, 1, 1]


def _as_a_real_cell(session: CellSession, state: dict[str, Any]) -> None:
    """Restore the devices (a real sensor keeps its offsets) but nothing of the process."""
    load(session, {k: v for k, v in state.items() if k != "cell"})


load = CellSession.load_emulator_state


def test_the_first_press_after_a_resume_on_a_real_cell_is_made_twice(
        tmp_path: Path, presses: list[int]) -> None:
    """A real resume keeps nothing of the process (the guard's reference is in no device)."""
    config = cell_config("link+jr3", tmp_path, 3, 2, False)
    _run(config, tmp_path / "run", 1)
    with mock.patch.object(CellSession, "load_emulator_state", _as_a_real_cell):
        _run(config, tmp_path / "run", 3, resume=True)
    assert presses == [2, 2, 1]


def test_an_emulated_resume_goes_on_with_its_reference(
        tmp_path: Path, presses: list[int]) -> None:
    """The emulated sensor is restored with its zero: the reference holds (bit-identical)."""
    config = cell_config("link+jr3", tmp_path, 3, 2, False)
    _run(config, tmp_path / "run", 1)
    _run(config, tmp_path / "run", 3, resume=True)
    assert presses == [2, 1, 1]
