"""Where each move's in-position falls on the controller's tick grid, from the records' windows.

The controller runs its motion on a fixed grid of ``tick_s`` (4 ms): a command counts
from the first tick after it arrives plus the planning delay, and the robot is in
position a whole number of ticks later (:func:`~forcelearn.tools.twin.arm_model.profile`).
A poll sees it in position within one poll period after that tick. The records give
each move's command (:func:`~forcelearn.tools.twin.arm.command_s`) and the poll that saw
it in position; the grid's phase on the records' clock, the delay from the recorded
command to the controller counting it, and how much longer that delay is after a
multi-sample burst read (whose recorded span is not the read's length) are the three
numbers that place every move's in-position on its own tick:

    in position = phase + tick * (ceil((command + delay [+ after_burst] - phase) / tick)
                  + ticks of motion - 1)

They are found as the values that put the most moves' in-position inside their
detection windows ``(recorded - period, recorded]``: for a phase, each move allows an
interval of the delay (its window's first and last tick), and a sweep over the
intervals' ends finds the delay most of them share, for the moves after a burst read
and the others apart. The windows' edges, at many distinct phases of the moves, pin the
grid to a fraction of a tick.

Why not the mean over the command's phase (:func:`~forcelearn.tools.twin.arm_model.in_position_s`):
each move meets the grid at its own phase, so the mean is up to a tick off on any one
move. On a low-noise copy of hidden cell 25 of seed 7 the mean model put the moves'
in-position 0.9 ms late (median; 5-95 % from -1.5 to +3.6 ms) against the tick the emulated
controller reports it, and the relaxation ratio fitted 0.0045 low (about 3 sigma); this grid
puts 92 % of its 1,796 site moves on that tick (the rest one tick early: commands whose
arrival falls within the JR3 adapter's +-0.5 ms loop phase of a tick's edge).

Units: s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PHASES = 64
"""Grid phases tried per tick (a 4 ms tick: steps of 0.0625 ms)."""
DELAY_REACH_TICKS = 3
"""The delay is looked for within this many ticks of the timing fit's start delay."""
MIN_GROUP = 8
"""Fewer moves than this after a burst read: one delay for every move."""
MIN_SHARE = 0.97
"""The grid is used only when it puts at least this share of the moves inside their
windows (else the controller, or the arm's ticks of motion, are not the modelled ones: the
mean model is kept). The Net F/T example cell's 40-trial run with its identification's arm
(1.4 % more acceleration than the emulated arm's): 93 %, and its grid put the moves 3.9 ms
RMS off the emulated tool's first tick inside the band where the mean model was 2.0 ms off
(session 17's measure)."""
MAX_PHASE_RUN = PHASES // 4
"""The phases that explain the most windows must lie within this many steps (a quarter of the
tick, 1 ms of 4): where moves end before their first poll, every window is wide and every
phase explains them all (hidden cell 23 of seed 9: all 64), and the grid is not determined.
A short run's 110 moves pin it to 1 ms, a study cell's 2,000 to 0.06-0.4 ms."""
MIN_GAIN = 0.5
"""...and the grid must explain at least this share of the windows the mean model's times
miss (seed 7 cell 25: 0.62; the Net F/T example above: 0.09)."""


@dataclass(frozen=True)
class TickGrid:
    """The controller's tick grid on the records' clock (s) and the share it explains."""

    phase_s: float
    """A tick's time modulo ``tick_s`` on the records' clock, s."""
    delay_s: float
    """From a recorded command to the controller counting it (link time and planning), s."""
    after_burst_s: float
    """Added to the delay after a multi-sample burst read, s (its span is not its length)."""
    tick_s: float
    share: float
    """Share of the timed moves whose grid in-position lies inside its detection window."""
    moves: int

    def in_position_s(self, command_s: np.ndarray, after_burst: np.ndarray,
                      motion_ticks: np.ndarray) -> np.ndarray:
        """Each move's in-position on the grid, s (shapes alike; ``after_burst`` bool)."""
        tick = self.tick_s
        start = np.ceil((command_s + self.delay_s + self.after_burst_s * after_burst
                         - self.phase_s) / tick - 1e-9)
        result: np.ndarray = self.phase_s + tick * (start + motion_ticks - 1.0)
        return result


def whole_ticks(fractional: np.ndarray) -> np.ndarray:
    """The tick a move is in position at, counted from its first tick of motion (1 = that one).

    :func:`~forcelearn.tools.twin.arm_model.profile`'s ticks carry the band crossing's
    fraction of the tick it falls in (``n - 1 + f``, ``0 < f <= 1``): the controller sees
    it at the end of that tick, the ``n``-th.
    """
    result: np.ndarray = np.maximum(np.ceil(fractional - 1e-9), 1.0)
    return result


def _allowed_delays(command_s: np.ndarray, motion_ticks: np.ndarray, recorded_s: np.ndarray,
                    period_s: float, phase_s: float, tick_s: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(low, high] of the delay that puts each move's in-position inside its window, s.

    Empty (low >= high) where no tick of the grid at ``phase_s`` falls in the window.
    """
    base = (recorded_s - phase_s) / tick_s - (motion_ticks - 1.0)
    first = np.floor(base - period_s / tick_s + 1e-9) + 1.0
    last = np.floor(base + 1e-9)
    low = (first - 1.0) * tick_s + phase_s - command_s
    high = last * tick_s + phase_s - command_s
    return low, high


def _best_delay(low: np.ndarray, high: np.ndarray, prior_s: float, reach_s: float
                ) -> tuple[int, float]:
    """(moves, delay s): the delay inside the most intervals, nearest ``prior_s`` among equals.

    A sweep over the intervals' ends (an end before a start at the same value: touching
    intervals do not overlap); the delay is the middle of the best stretch.
    """
    keep = (high > low) & (high > prior_s - reach_s) & (low < prior_s + reach_s)
    if not keep.any():
        return 0, prior_s
    ends = np.concatenate([low[keep], high[keep]])
    step = np.concatenate([np.ones(int(keep.sum())), -np.ones(int(keep.sum()))])
    order = np.lexsort((step, ends))
    ends, covered = ends[order], np.cumsum(step[order])
    most = int(covered.max())
    at = np.flatnonzero(covered[:-1] == most)
    if at.size == 0:
        return most, float(ends[-1])
    middles = 0.5 * (ends[at] + ends[at + 1])
    return most, float(middles[np.argmin(np.abs(middles - prior_s))])


def _circular_run(steps: list[int]) -> int:
    """How many phase steps (of ``PHASES``, wrapping) the shortest arc holding ``steps`` spans."""
    ordered = sorted(steps)
    gaps = np.diff(np.array([*ordered, ordered[0] + PHASES]))
    return PHASES - int(gaps.max()) + 1


def fit_grid(command_s: np.ndarray, after_burst: np.ndarray, motion_ticks: np.ndarray,
             recorded_s: np.ndarray, period_s: float, tick_s: float, prior_delay_s: float,
             mean_s: np.ndarray | None = None) -> TickGrid | None:
    """The grid that puts the most timed moves inside their windows (1-D arrays alike).

    ``prior_delay_s``: the timing fit's start delay (the mean model's), near which the
    delay is looked for; ``mean_s``: the mean model's in-position of each move, s. None
    (the grid not determined) when there are too few moves, no polling period, the best
    grid explains fewer than ``MIN_SHARE`` of them, the phases that explain the most spread
    over more than ``MAX_PHASE_RUN`` steps, or it explains less than ``MIN_GAIN`` of the
    windows ``mean_s`` misses.
    """
    n = int(command_s.size)
    if n < MIN_GROUP or not (period_s > 0 and tick_s > 0 and math.isfinite(prior_delay_s)):
        return None
    burst = after_burst.astype(bool)
    split = MIN_GROUP <= int(burst.sum()) <= n - MIN_GROUP
    groups = [burst, ~burst] if split else [np.ones(n, dtype=bool)]
    reach = DELAY_REACH_TICKS * tick_s
    found: list[tuple[int, float, list[float]]] = []
    for k in range(PHASES):
        phase = k * tick_s / PHASES
        low, high = _allowed_delays(command_s, motion_ticks, recorded_s, period_s, phase,
                                    tick_s)
        best = [_best_delay(low[g], high[g], prior_delay_s, reach) for g in groups]
        found.append((sum(b[0] for b in best), phase, [b[1] for b in best]))
    most = max(f[0] for f in found)
    if most < MIN_SHARE * n:
        return None
    best_k = [k for k, f in enumerate(found) if f[0] == most]
    if _circular_run(best_k) > MAX_PHASE_RUN:
        return None
    if mean_s is not None:
        missed = n - int(np.sum((mean_s > recorded_s - period_s) & (mean_s <= recorded_s)))
        if missed > 0 and most - (n - missed) < MIN_GAIN * missed:
            return None
    # the middle of the phases that explain the most (a circular run: the grid wraps)
    angles = 2.0 * np.pi * np.array(best_k) / PHASES
    middle = math.atan2(float(np.mean(np.sin(angles))), float(np.mean(np.cos(angles))))
    target = (middle / (2.0 * np.pi)) % 1.0 * PHASES
    k = min(best_k, key=lambda j: min(abs(j - target), PHASES - abs(j - target)))
    count, phase, delays = found[k]
    if split:
        after, delay = delays[0] - delays[1], delays[1]
    else:
        after, delay = 0.0, delays[0]
    return TickGrid(phase, delay, after, tick_s, count / n, n)
