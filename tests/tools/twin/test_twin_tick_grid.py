"""The records' detection windows place each move's in-position on the controller's own tick."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion
from forcelearn.site.config import load_cell_config
from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.fuzz.fault_campaign import cell_config
from forcelearn.tools.twin.arm import (
    ArmFit,
    detection_period_s,
    fit_arm,
    polling_of,
    true_in_position_s,
    with_grid,
)
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.source import read_run_records
from forcelearn.tools.twin.tick_grid import MIN_SHARE, TickGrid, fit_grid, whole_ticks

TICK_S = 0.004
PERIOD_S = 0.0435
"""A computer link's status poll at 9600 baud, s: each window is about eleven ticks wide."""


def _moves(seed: int, phase_s: float, after_burst_s: float, count: int = 800,
           burst_share: float = 0.6) -> tuple[np.ndarray, ...]:
    """(command, after_burst, motion ticks, true in-position, recorded) of a polled controller.

    The controller counts each command from its own 4 ms grid (``phase_s`` on the recorded
    clock); polls ``PERIOD_S`` apart from a random phase after each command record the
    first that sees the move in position.
    """
    rng = np.random.default_rng(seed)
    command = np.cumsum(rng.uniform(0.3, 0.9, count))
    burst = rng.random(count) < burst_share
    ticks = rng.integers(3, 60, count).astype(float)
    truth = TickGrid(phase_s, 0.1227, after_burst_s, TICK_S, 1.0, count)
    exact = truth.in_position_s(command, burst, ticks)
    first_poll = command + rng.uniform(0.0, PERIOD_S, count)
    recorded = first_poll + np.ceil((exact - first_poll) / PERIOD_S - 1e-12) * PERIOD_S
    return command, burst, ticks, exact, recorded


@pytest.mark.parametrize(("seed", "phase_s", "after_burst_s"),
                         [(0, 0.0, -0.0017), (1, 0.0013, -0.0017), (2, 0.0031, 0.0009)])
def test_the_grid_puts_the_moves_on_their_own_tick(seed: int, phase_s: float,
                                                   after_burst_s: float) -> None:
    """The grid's phase, delay and after-burst offset come back; 98 % of moves on their tick."""
    command, burst, ticks, exact, recorded = _moves(seed, phase_s, after_burst_s)
    grid = fit_grid(command, burst, ticks, recorded, PERIOD_S, TICK_S, prior_delay_s=0.125)
    assert grid is not None
    placed = grid.in_position_s(command, burst, ticks)
    assert np.mean(np.abs(placed - exact) < TICK_S / 4) >= 0.98
    assert grid.share >= 0.99
    off = (grid.phase_s - phase_s + TICK_S / 2) % TICK_S - TICK_S / 2
    assert abs(off) < TICK_S / 8
    assert grid.after_burst_s == pytest.approx(after_burst_s, abs=0.0005)


def test_one_delay_for_every_move_when_none_waited_for_a_burst() -> None:
    """No move after a burst read: one delay, no after-burst offset."""
    command, burst, ticks, exact, recorded = _moves(3, 0.0021, 0.0, burst_share=0.0)
    grid = fit_grid(command, burst, ticks, recorded, PERIOD_S, TICK_S, prior_delay_s=0.12)
    assert grid is not None and grid.after_burst_s == 0.0
    assert np.mean(np.abs(grid.in_position_s(command, burst, ticks) - exact) < TICK_S / 4) >= 0.98


def test_no_grid_where_the_windows_do_not_follow_one() -> None:
    """A controller off its modelled ticks by tens of ms: the mean model is kept (None)."""
    command, burst, ticks, _, recorded = _moves(4, 0.0, -0.0017)
    scattered = recorded + np.random.default_rng(5).normal(0.0, 0.03, recorded.size)
    assert fit_grid(command, burst, ticks, scattered, PERIOD_S, TICK_S, 0.125) is None
    assert MIN_SHARE > 0.5


def test_no_grid_where_every_phase_explains_the_windows() -> None:
    """Windows many ticks wide at every phase (moves ending before their first poll): None."""
    command, burst, ticks, _, recorded = _moves(7, 0.0013, -0.0017)
    wide = 0.4
    assert fit_grid(command, burst, ticks, recorded + 0.5 * wide, wide, TICK_S, 0.125) is None


def test_no_grid_without_a_polling_period_or_with_too_few_moves() -> None:
    """Exact recorded times (no polling) or a handful of moves: no grid."""
    command, burst, ticks, _, recorded = _moves(6, 0.0, -0.0017, count=40)
    assert fit_grid(command, burst, ticks, recorded, 0.0, TICK_S, 0.125) is None
    assert fit_grid(command[:5], burst[:5], ticks[:5], recorded[:5], PERIOD_S, TICK_S,
                    0.125) is None


def test_whole_ticks_count_the_tick_the_band_crossing_falls_in() -> None:
    """A crossing inside a tick is seen at that tick's end; within the band at once: tick 1."""
    assert whole_ticks(np.array([0.5, 3.0, 3.2, 7.99])).tolist() == [1.0, 3.0, 4.0, 8.0]


@pytest.mark.parametrize("seed", [0, 1])
def test_a_short_emulated_run_is_placed_on_the_emulated_arms_own_ticks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int,
) -> None:
    """With the arm's timing known, the grid finds the tick the emulated arm came in position.

    The mean over the grid's phase (the timing model without the grid) is on that tick
    only by chance.
    """
    entries: list[float] = []
    advance_keys, command = ArmMotion.advance_keys, ArmMotion.command

    def logged_keys(self: ArmMotion, t_s: float) -> tuple[list[Any], int]:
        # one tick at a time (the same motion), to see the tick the controller first
        # reports in position: the reference stopped on the target, the tool in the band
        keys: list[Any] = []
        rest = 0
        for index in range(self.tick_index + 1, self.tick_at(t_s) + 1):
            more, jumped = advance_keys(self, index * self.params.tick_s)
            keys += more
            rest += jumped
            if getattr(self, "_logged_goal", None) is not None and self.in_position:
                entries.append(self.tick_index * self.params.tick_s)
                self._logged_goal = None  # type: ignore[attr-defined]
        return keys, rest

    def logged_command(self: ArmMotion, target: Pose, t_s: float) -> None:
        command(self, target, t_s)
        self._logged_goal = (target.x_mm, target.y_mm, target.z_mm)  # type: ignore[attr-defined]

    monkeypatch.setattr(ArmMotion, "advance_keys", logged_keys)
    monkeypatch.setattr(ArmMotion, "command", logged_command)
    config = cell_config("link+jr3", tmp_path, trials=4, steps=20, probe=False)
    run, checkpoint = run_state.prepare_run(config, tmp_path / "run", None, seed, resume=False)
    engine.execute(run, checkpoint)

    data = to_arrays(read_run_records(tmp_path / "run"))
    cell = load_cell_config(config)
    period = detection_period_s(data, polling_of(cell.robot, cell.emulator.arm).period_s)
    band = cell.emulator.arm.in_position_mm
    timed = fit_arm(data, base_arm(), band, period).timing
    assert timed is not None
    # the emulated arm's own timing; the start delay the moves' records give it (the link's
    # time to send the command is in it)
    truth = {**base_arm(), "start_delay_s": timed["start_delay_s"]}
    arm = ArmFit(truth, dict.fromkeys(truth, 1e-3), 0.0, 0, period_s=period, timing=truth)
    gridded = with_grid(arm, data, band, TICK_S)
    assert gridded.grid is not None
    moved = data.valid & np.isfinite(data.move_mm) & (data.move_mm > 0)
    logged = np.array(entries)

    def on_logged_tick(found: ArmFit) -> float:
        placed = true_in_position_s(data, found, band)[moved]
        nearest = np.min(np.abs(logged[None, :] - placed[:, None]), axis=1)
        return float(np.mean(nearest < TICK_S / 8))

    placed, by_mean = on_logged_tick(gridded), on_logged_tick(arm)
    print(f"on the emulated arm's tick: grid {placed:.3f}, mean model {by_mean:.3f}")
    assert placed >= 0.85  # the JR3 loop's phase after a burst: +-0.5 ms
    assert by_mean <= 0.35
