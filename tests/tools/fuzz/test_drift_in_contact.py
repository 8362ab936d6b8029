"""A steady drift of the sensor's zero near the force limit: the press guard keeps its headroom."""

from __future__ import annotations

import random
from pathlib import Path
from unittest import mock

import pytest

from forcelearn.cell import Cell
from forcelearn.press_guard import DriftCheck, drift_rate_bound_n_per_s, unseen_drift_n
from forcelearn.tools.fuzz import fault_campaign
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


NETFT_TICK = 108
"""fault_extra --seed 0's second Net F/T run: the drift starts in trial 1, after trial 0's zero
check; the next session (resumed from that checkpoint, the drift going on from its first call)
pressed from a zero 4.2 s old with 0.5 N of drift no check had seen, and met 60.04 N."""


def _netft_drift(tmp_path: Path, settings: tuple[str, ...] = ()) -> fault_campaign.RunReport:
    config = cell_config("link+netft", tmp_path, trials=2, steps=8, probe=False,
                         settings=[*MATERIALS["stiff8-small"], *settings])
    injector = ExtraInjector({NETFT_TICK: [("sensor", "drift")]}, random.Random(0))
    with mock.patch.object(fault_campaign, "SESSION_CAP", 3):  # it passed 60 N in session 2
        return one_run("link+netft", config, tmp_path / "run", 0, 141, 0, 0, 1e9,
                       injector=injector)


def test_a_drift_no_check_saw_stays_in_the_headroom(tmp_path: Path) -> None:
    """The Net F/T's drift since trial 0's check: the guard keeps the unseen drift's headroom."""
    report = _netft_drift(tmp_path)
    assert report.over_limit == 0, report.max_contact_n
    assert report.zeros_in_contact == 0


def test_without_the_unseen_drift_the_same_run_passes_the_limit(tmp_path: Path) -> None:
    """The case above is the one near the limit: with no unseen drift allowed it passes 60 N."""
    report = _netft_drift(tmp_path, ("filter.bias_drift_max_n_per_s=0.0",))
    assert report.over_limit > 0


def test_a_stale_zero_is_checked_before_a_press_near_the_limit(tmp_path: Path) -> None:
    """A fast unseen drift allowed: the cell retracts, checks the zero and presses again.

    A sensor allowed 1 N/s of unseen drift would keep newtons of headroom within seconds of
    its zero: before a press cut near the limit the run checks the zero in free space instead
    (and a zero that moved voids the trial), never over the limit, no zero in contact.
    """
    refreshes: list[float] = []
    refresh = Cell._refresh

    def counted(cell: Cell) -> None:
        refreshes.append(cell.time_s - cell.zero_time_s)
        refresh(cell)

    with mock.patch.object(Cell, "_refresh", counted):
        report = _netft_drift(tmp_path, ("filter.bias_drift_max_n_per_s=1.0",))
    assert refreshes
    assert report.over_limit == 0, report.max_contact_n
    assert report.zeros_in_contact == 0


@pytest.mark.parametrize("elapsed_s", [0.0, 4.2])
def test_the_unseen_drift_grows_with_the_zero_s_age(elapsed_s: float) -> None:
    """0.5 N of drift 4.2 s after the zero is inside the default 0.2 N/s bound."""
    assert unseen_drift_n(0.2, elapsed_s) == pytest.approx(0.2 * elapsed_s)
    assert unseen_drift_n(0.2, -1.0) == 0.0
