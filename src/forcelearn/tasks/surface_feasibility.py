"""Is the desired force still within reach? The run's own estimate, from its recent trials.

The probe refuses a force whose depth it cannot allow at the start
(:func:`~forcelearn.tasks.surface_probe.choose_output_map`); wear can make a
force that was in reach out of reach later (the foam softens: the same force
needs more compression, and the backing does not move). After every trial
:func:`assess` looks at the last ``window`` trials' Y commands and forces:

* the **worn stiffness**: the force's slope against the commanded Y within each
  step, pooled over the steps (the search's spread around μ gives the slope;
  the step's own surface Y drops out); without enough spread (commands held
  at the range's end) the probe's stiffness, which wear only lowers, so the
  depth it predicts is a lower bound;
* per step, the mean command and force; where steps (at least
  ``MIN_STEP_SHARE`` of them: a soft patch of foam is enough) press within
  ``AT_END_MM`` of the deep end of the output range on average over the
  window, and the force there, extrapolated to the end with the stiffness,
  stays under the desired force minus the band, the force is out of reach
  there: the Y that would give it is
  ȳ − (F_d − F̄) / k. Below the deepest allowed Y (``probe.max_depth_mm``
  below the probed contact, the workspace) it is the **foam** that cannot
  give it; above, it is the **range** (its wear shift held at the limit).
  Depths are given below the probed contact at that step (where the backing's
  distance was measured from).
  The symmetric case (the range's top still presses too hard) is **range top**.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

FEASIBILITY_WINDOW = 10
"""Trials the run's estimate looks back over (the convergence window)."""
AT_END_MM = 2.0
"""A mean command within this of the range's end counts as pressing at its end, mm (the force
is extrapolated the rest of the way)."""
MIN_SPREAD_MM = 0.05
"""Least RMS spread of the commands within a step for the run's own stiffness estimate, mm."""
MIN_STEP_SHARE = 0.1
"""Least share of a trial's steps out of reach for a finding (2 of 20)."""
STIFFNESS_CLIP = (0.1, 1.5)
"""The run's stiffness estimate is held within these multiples of the probe's."""


@dataclass(frozen=True)
class Feasibility:
    """The desired force out of reach: where, why, and the figures (mm, N, N/mm)."""

    reason: str
    """"foam" (more depth than allowed), "range" (the range's deep end), "range top"."""
    trial: int
    """The last trial of the window the estimate is from."""
    step: int
    """The step (1: the first) with the least margin."""
    command_y_mm: float
    """Mean Y commanded at that step over the window."""
    force_n: float
    """Mean force read there."""
    desired_force_n: float
    needed_y_mm: float
    """The Y that would give the desired force (the worn stiffness)."""
    needed_depth_mm: float
    """How far below the probed contact the desired force needs to press."""
    contact_y_mm: float
    """The probed contact Y at that step (interpolated in Z, before any wear)."""
    allowed_bottom_y_mm: float
    """The deepest Y allowed."""
    allowed_depth_mm: float
    """How far below the probed contact the map may press."""
    force_at_bottom_n: float
    """The force the run's figures give at the deepest allowed Y there."""
    range_end_y_mm: float
    """The output range's end there (shift included)."""
    worn_stiffness_n_per_mm: float
    stiffness_source: str
    """"run" (the run's own estimate) or "probe" (too little spread to estimate)."""
    probe_stiffness_n_per_mm: float

    def text(self) -> str:
        """One line for a warning, summary.json's diagnosis and the live view."""
        k = self.worn_stiffness_n_per_mm
        stiffness = (
            f"worn stiffness {k:.2f} N/mm (the probe's {self.probe_stiffness_n_per_mm:.2f})"
            if self.stiffness_source == "run"
            else f"stiffness at most the probe's {k:.2f} N/mm (too little spread to estimate "
            "the worn one)"
        )
        where = (
            f"up to trial {self.trial}, step {self.step} pressed at y = {self.command_y_mm:.1f} mm "
            f"and read {self.force_n:.1f} N of the desired {self.desired_force_n:.1f} N"
        )
        if self.reason == "foam":
            return (
                f"the desired force is out of the foam's reach: {where}; with the {stiffness} "
                f"it needs y = {self.needed_y_mm:.1f} mm, {self.needed_depth_mm:.1f} mm below "
                f"the probed contact (y = {self.contact_y_mm:.1f} mm), but "
                f"{self.allowed_depth_mm:.1f} mm are allowed (deepest y = "
                f"{self.allowed_bottom_y_mm:.1f} mm: probe.max_depth_mm, "
                "safety.workspace_min_mm; beyond it the backing); the foam gives about "
                f"{self.force_at_bottom_n:.1f} N there: lower task.desired_force_n, or use a "
                "thicker or stiffer foam"
            )
        if self.reason == "range":
            return (
                f"the desired force is beyond the output range's deep end: {where}; with the "
                f"{stiffness} it needs y = {self.needed_y_mm:.1f} mm, below the range's end "
                f"y = {self.range_end_y_mm:.1f} mm (the foam allows down to "
                f"{self.allowed_bottom_y_mm:.1f} mm): widen the range (probe.wear_margin, or "
                "task.max_offset_mm if you set it)"
            )
        return (
            f"the output range's top still presses too hard: {where}; with the {stiffness} "
            f"the desired force is at y = {self.needed_y_mm:.1f} mm, above the range's top "
            f"y = {self.range_end_y_mm:.1f} mm: check task.desired_force_n against the sponge "
            "and task.output_centre_y_mm / task.max_offset_mm if you set them"
        )


def worn_stiffness(
    commands_y_mm: np.ndarray, forces_n: np.ndarray
) -> float | None:
    """The force's slope against Y within each step (columns), pooled; None without spread.

    Arrays are trials × steps, NaN where a step did not run. Returns k > 0 in
    N/mm (force rises as Y goes deeper, −dF/dY), or None.
    """
    ok = np.isfinite(commands_y_mm) & np.isfinite(forces_n)
    sxx = sxy = 0.0
    count = 0
    for j in range(commands_y_mm.shape[1]):
        y, f = commands_y_mm[ok[:, j], j], forces_n[ok[:, j], j]
        if len(y) < 3:
            continue
        dy, df = y - y.mean(), f - f.mean()
        sxx += float(dy @ dy)
        sxy += float(dy @ df)
        count += len(y)
    if count == 0 or sxx < count * MIN_SPREAD_MM**2 or sxy >= 0:
        return None
    return -sxy / sxx


def assess(
    commands_y_mm: Sequence[Sequence[float]],
    forces_n: Sequence[Sequence[float]],
    range_bottom_y_mm: Sequence[Sequence[float]],
    range_top_y_mm: Sequence[Sequence[float]],
    contact_y_mm: Sequence[float],
    *,
    trial: int,
    desired_force_n: float,
    band_n: float,
    probe_stiffness_n_per_mm: float,
    allowed_bottom_y_mm: float,
) -> Feasibility | None:
    """The desired force out of reach over these trials (module docstring), or None.

    The first four arguments hold one row per trial of the window and one value
    per step (mm or N; rows may be shorter: failed trials); ``contact_y_mm`` the
    probed contact Y of each step (mm).
    """
    steps = max((len(row) for row in commands_y_mm), default=0)
    if steps == 0 or not math.isfinite(probe_stiffness_n_per_mm):
        return None

    def table(rows: Sequence[Sequence[float]]) -> np.ndarray:
        out = np.full((len(rows), steps), np.nan)
        for i, row in enumerate(rows):
            out[i, : len(row)] = row
        return out

    y, f = table(commands_y_mm), table(forces_n)
    bottom, top = table(range_bottom_y_mm), table(range_top_y_mm)
    k_run = worn_stiffness(y, f)
    low, high = STIFFNESS_CLIP
    k = probe_stiffness_n_per_mm if k_run is None else float(
        np.clip(k_run, low * probe_stiffness_n_per_mm, high * probe_stiffness_n_per_mm)
    )
    source = "probe" if k_run is None else "run"
    with np.errstate(invalid="ignore"):
        ran = np.isfinite(y) & np.isfinite(f)
        counts = ran.sum(axis=0)
        seen = counts >= max(1, len(y) // 2)
        if not seen.any():
            return None
        mean = {name: np.nanmean(np.where(ran, arr, np.nan), axis=0)[seen]
                for name, arr in (("y", y), ("f", f), ("bottom", bottom), ("top", top))}
    index = np.flatnonzero(seen)
    at_bottom = mean["f"] + k * np.maximum(mean["y"] - mean["bottom"], 0.0)
    at_top = mean["f"] - k * np.maximum(mean["top"] - mean["y"], 0.0)
    deep = (mean["y"] <= mean["bottom"] + AT_END_MM) & (at_bottom < desired_force_n - band_n)
    shallow = (mean["y"] >= mean["top"] - AT_END_MM) & (at_top > desired_force_n + band_n)
    needed = mean["y"] - (desired_force_n - mean["f"]) / k
    contact = np.asarray(contact_y_mm, dtype=float)[index]
    least = max(1, round(MIN_STEP_SHARE * steps))
    if deep.sum() >= least:
        worst = int(np.argmin(np.where(deep, needed - allowed_bottom_y_mm, np.inf)))
        reason = "foam" if float(np.median(needed[deep])) < allowed_bottom_y_mm else "range"
        end = float(mean["bottom"][worst])
    elif shallow.sum() >= least:
        worst = int(np.argmax(np.where(shallow, needed, -np.inf)))
        reason, end = "range top", float(mean["top"][worst])
    else:
        return None
    return Feasibility(
        reason=reason,
        trial=trial,
        step=int(index[worst]) + 1,
        command_y_mm=float(mean["y"][worst]),
        force_n=float(mean["f"][worst]),
        desired_force_n=desired_force_n,
        needed_y_mm=float(needed[worst]),
        needed_depth_mm=float(contact[worst] - needed[worst]),
        contact_y_mm=float(contact[worst]),
        allowed_bottom_y_mm=allowed_bottom_y_mm,
        allowed_depth_mm=float(contact[worst]) - allowed_bottom_y_mm,
        force_at_bottom_n=float(mean["f"][worst] + k * (mean["y"][worst] - allowed_bottom_y_mm)),
        range_end_y_mm=end,
        worn_stiffness_n_per_mm=k,
        stiffness_source=source,
        probe_stiffness_n_per_mm=probe_stiffness_n_per_mm,
    )
