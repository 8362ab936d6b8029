"""The emulated arm's motion on its tick grid, over arrays of move lengths: the twin's arm model.

The emulated arm (:class:`~forcelearn.emulators.physics.arm_motion.ArmMotion`) runs a
trapezoidal reference on a ``tick_s`` grid (``v = min(v + a dt, speed, sqrt(2 a
remaining))``, ``s += v dt``) and a tool that follows it through a first-order lag
sampled on the same grid (``tool += (1 - exp(-dt / lag)) (ref - tool)``); it is in
position at the first tick where the reference has stopped on the target and the tool
is within the band. This module runs the same recursion for many move lengths at once,
so the twin's timing and the path its foam model follows are the emulator's, tick for
tick, not a continuous-time stand-in (which read a lag 16 % long off polled moves, and
left the relaxing part of the force 1 % short after a step: a relaxation ratio 1 % high).

A move's motion begins at the first tick after its command plus the start delay; the
command's phase on the grid is unknown (uniform), so the time from command to in
position is taken as ``start_delay + tick / 2 + (N - 1/2) tick``, with ``N`` the ticks
of motion, counted with its fraction (the tool's error crosses the band between two
ticks, geometrically once the reference has stopped; where the tool is inside the band
before the reference stops, the share of the tick the reference's last step took): smooth
in the parameters, which a least-squares fit needs, and equal to the emulator's mean over
phases and lengths. A move shorter than the band is in position when its reference stops
(a slow arm's 0.1 mm step takes 7 ticks), not at its first tick of motion.

Units: mm, s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TICK_S = 0.004
"""The emulated controller's interpolation period, s (``[emulator.arm] tick_s``)."""
MAX_TICKS = 20000
"""Longest motion followed, ticks (80 s at 4 ms): a longer one is cut there."""
ROUND_MM = 1e-3
"""Move lengths are grouped to this (mm): the model runs once per distinct length."""
_SNAP_MM = 1e-4
"""The emulator's snap of the lagging tool onto a stopped reference, mm."""


@dataclass(frozen=True)
class Profile:
    """The tool's motion over each distinct move length, on the tick grid."""

    lengths_mm: np.ndarray
    """(U,) the distinct lengths, mm."""
    inverse: np.ndarray
    """Index into ``lengths_mm`` of each move of the input (input's shape)."""
    ticks: np.ndarray
    """(U,) ticks of motion to in position, with the fraction of the band crossing."""
    share: np.ndarray | None
    """(U, L + 1) share of the path the tool has done after 0..L ticks (1 after in
    position); None when not asked for."""


def profile(distance_mm: np.ndarray, arm: dict[str, float], band_mm: float,
            keep_path: bool = False, speed_mm_s: np.ndarray | None = None) -> Profile:
    """Run the emulator's motion for every distinct length of ``distance_mm`` (mm).

    ``arm`` holds ``default_speed_mm_s``, ``accel_mm_s2``, ``lag_s`` and optionally
    ``tick_s``. ``keep_path``: also return the tool's share of the path per tick.
    ``speed_mm_s`` (``distance_mm``'s shape): each move's own speed, mm/s, instead of
    ``default_speed_mm_s``; the model then runs once per distinct (length, speed) pair,
    all pairs in one pass over the ticks.
    """
    tick = float(arm.get("tick_s", TICK_S))
    accel, lag = arm["accel_mm_s2"], arm["lag_s"]
    flat = np.nan_to_num(np.asarray(distance_mm, dtype=float))
    rounded = np.round(np.maximum(flat, 0.0) / ROUND_MM)
    speed: float | np.ndarray
    if speed_mm_s is None:
        lengths, inverse = np.unique(rounded, return_inverse=True)
        speed = arm["default_speed_mm_s"]
    else:
        pairs = np.column_stack([rounded.ravel(),
                                 np.broadcast_to(speed_mm_s, flat.shape).ravel()])
        unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
        lengths, speed = unique[:, 0], unique[:, 1]
    d = lengths * ROUND_MM
    keep = math.exp(-tick / lag) if lag > 0 else 0.0
    gain = 1.0 - keep
    s, v, tool = np.zeros_like(d), np.zeros_like(d), np.zeros_like(d)
    # a move of no length is in position at once; any other when its reference has stopped
    # on the target with the tool inside the band (a move shorter than the band too)
    ticks = np.where(d > 0, np.nan, 0.0)
    error = d.copy()
    shares = [np.where(d > 0, 0.0, 1.0)] if keep_path else []
    for i in range(1, MAX_TICKS + 1):
        moving = s < d
        before = s
        step = np.minimum(np.minimum(v + accel * tick, speed),
                          np.sqrt(2.0 * accel * np.maximum(d - s, 0.0)))
        s = np.where(moving, np.minimum(d, s + step * tick), s)
        v = np.where(moving & (s < d), step, 0.0)
        tool = tool + gain * (s - tool)
        stopped = s >= d
        tool = np.where(stopped & (np.abs(s - tool) < _SNAP_MM), s, tool)
        new_error = d - tool
        reached = stopped & (new_error <= band_mm) & np.isnan(ticks)
        if reached.any():
            ticks = np.where(reached, i - 1 + _crossing_fraction(
                moving, before, step * tick, d, error, new_error, band_mm), ticks)
        error = new_error
        if keep_path:
            shares.append(np.where(d > 0, tool / np.maximum(d, 1e-12), 1.0))
        waiting = np.isnan(ticks)
        if not waiting.any():
            break
        if not keep_path and keep > 0 and band_mm > _SNAP_MM and stopped[waiting].all():
            ticks = np.where(waiting, _decay_ticks(i, error, band_mm, keep), ticks)
            break
    ticks = np.where(np.isnan(ticks), float(MAX_TICKS), ticks)
    share = np.stack(shares, axis=1) if keep_path else None
    return Profile(d, inverse.reshape(flat.shape), ticks, share)


def _crossing_fraction(moved: np.ndarray, before_mm: np.ndarray, step_mm: np.ndarray,
                       d: np.ndarray, error: np.ndarray, new_error: np.ndarray,
                       band_mm: float) -> np.ndarray:
    """The share (0, 1] of the tick in which a move comes in position that it took.

    The controller sees it at the tick's end either way (:func:`~.tick_grid.whole_ticks`);
    the share keeps the mean time smooth in the arm's parameters. A reference that stopped
    in this tick (``moved``; the tool then inside the band, or entering it): the share of
    the tick its last step used. One stopped before: the tool's error decays geometrically,
    and the share is where it crosses the band. (Taking every crossing as geometric put a
    slow arm's moves whose tool was inside the band before the reference stopped, 316
    mm/s^2 and a 13 ms lag, a whole tick early.)
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        last_step = np.clip((d - before_mm) / step_mm, 0.0, 1.0)
        decay = np.log(error / band_mm) / np.log(error / np.maximum(new_error, 1e-300))
    stopped_share = np.where(np.isfinite(decay), np.clip(decay, 0.0, 1.0), 1.0)
    share = np.where(moved, np.where(np.isfinite(last_step), last_step, 1.0), stopped_share)
    result: np.ndarray = np.where(share > 0.0, share, 1.0)
    return result


def _decay_ticks(i: int, error: np.ndarray, band_mm: float, keep: float) -> np.ndarray:
    """Ticks to in position (with the crossing's fraction) of tools whose reference stopped.

    After tick ``i`` the error only decays, ``error keep^k``: the loop's band crossing in
    closed form, ``i + ln(error / band) / ln(1 / keep)`` (its tick ``i - 1 + k`` plus the
    fraction ``ln(e_(k-1) / band) / ln(1 / keep)``), ``MAX_TICKS`` when that is later. The
    tail of a long lag was most of the loop's ticks.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        tail = np.log(np.maximum(error, band_mm) / band_mm) / -math.log(keep)
    reach = i + np.ceil(tail - 1e-9)
    result: np.ndarray = np.where(reach > MAX_TICKS, float(MAX_TICKS), i + tail)
    return result


def in_position_s(distance_mm: np.ndarray, arm: dict[str, float], band_mm: float,
                  speed_mm_s: np.ndarray | None = None) -> np.ndarray:
    """Mean time (s) from a command to in position for moves of ``distance_mm``.

    ``start_delay + tick / 2 + (N - 1/2) tick`` (module doc); 0 motion for a move within
    the band. ``speed_mm_s``: each move's own speed (:func:`profile`).
    """
    tick = float(arm.get("tick_s", TICK_S))
    found = profile(distance_mm, arm, band_mm, speed_mm_s=speed_mm_s)
    ticks = found.ticks[found.inverse]
    motion = np.where(ticks > 0, ticks * tick, 0.0)
    result: np.ndarray = arm["start_delay_s"] + motion
    return result


def share_at_in_position(distance_mm: np.ndarray, arm: dict[str, float],
                         band_mm: float) -> np.ndarray:
    """Share (0..1) of each move's straight path the tool has done when it is in position.

    The lagging tool enters the in-position band short of the target: the emulated
    controller reports in position at the first tick within ``band_mm``, and the tool goes
    on toward the target with the servo lag. The share at the crossing (with its
    fraction, as :func:`profile` times it); 1 for a move of no length.
    """
    flat = np.nan_to_num(np.asarray(distance_mm, dtype=float))
    found = profile(flat, arm, band_mm, keep_path=True)
    assert found.share is not None  # asked for
    last = found.share.shape[1] - 1
    x = np.clip(found.ticks, 0.0, last)
    low = np.floor(x).astype(int)
    high = np.minimum(low + 1, last)
    rows = np.arange(found.lengths_mm.size)
    part = x - low
    share = found.share[rows, low] * (1.0 - part) + found.share[rows, high] * part
    share = np.where(found.lengths_mm > 0, np.clip(share, 0.0, 1.0), 1.0)
    result: np.ndarray = share[found.inverse]
    return result



def progress_mm(distance_mm: np.ndarray, arm: dict[str, float], band_mm: float,
                after_s: np.ndarray, speed_mm_s: np.ndarray | None = None) -> np.ndarray:
    """How far the tool has gone along each move ``after_s`` after its motion began, mm.

    ``after_s`` counts from the command plus the start delay (the origin of
    :func:`in_position_s`'s ticks); the share of the path after each tick of :func:`profile`,
    interpolated between ticks (the mean over the command's phase on the grid), and past the
    slowest move's in position the lag's geometric decay onto the target. 0 before the
    motion. Shapes: ``distance_mm``, ``after_s`` and ``speed_mm_s`` alike.
    """
    tick = float(arm.get("tick_s", TICK_S))
    lag = arm["lag_s"]
    found = profile(distance_mm, arm, band_mm, keep_path=True, speed_mm_s=speed_mm_s)
    assert found.share is not None  # asked for
    last = found.share.shape[1] - 1
    row = found.inverse
    x = np.asarray(after_s, dtype=float) / tick
    inside = np.clip(x, 0.0, float(last))
    low = np.floor(inside).astype(int)
    high = np.minimum(low + 1, last)
    part = inside - low
    share = found.share[row, low] * (1.0 - part) + found.share[row, high] * part
    keep = math.exp(-tick / lag) if lag > 0 else 0.0
    tail = 1.0 - (1.0 - found.share[row, last]) * keep ** np.maximum(x - last, 0.0)
    share = np.where(x > last, tail, np.where(x < 0, 0.0, share))
    result: np.ndarray = share * found.lengths_mm[row]
    return result
