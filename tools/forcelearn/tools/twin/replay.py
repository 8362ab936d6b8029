"""Replay a run's records on a twin: replayed against recorded force, trial by trial.

Two ways (``model``): ``"cell"`` (the default) sends the run's recorded commands to
the twin's wire-level emulated cell through the real drivers
(:mod:`forcelearn.tools.twin.replay_cell`), as CI runs the twin; ``"forward"``
predicts every burst with the fit's forward model (fast, no cell), the recorded
in-position times taken back by the twin link's mean polling latency.

The sensor's zero is not the cell's: it is read as a tare would, from the free-space
bursts (where the twin's forward model predicts no contact). The recorded minus the
replayed force there, taken as a random walk at the twin's drift rate (twice its
variance for the emulated cell: two walks apart) and profiled over the trials as the fit
does (:mod:`forcelearn.tools.twin.bias`), is added to the replayed force. Without it,
the emulated sensor's bias (the twin's own draw, not the run's) and the run's wander
apart by tenths of a newton over a 60-trial run and hide the force law
(``raw_overall_rms_n`` keeps that figure).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.records import TrialRecords
from forcelearn.site.config import CellConfig
from forcelearn.tools.twin.arm import (
    ArmFit,
    detection_period_s,
    polling_of,
    with_true_in_position,
)
from forcelearn.tools.twin.arrays import RecordArrays, to_arrays
from forcelearn.tools.twin.bias import build_chain, offsets, solve_biases, tare_zeros
from forcelearn.tools.twin.forward import predict_means
from forcelearn.tools.twin.problem import burst_weights
from forcelearn.tools.twin.replay_cell import replay_trials
from forcelearn.tools.twin.setup import base_arm, reading_of

MODELS = ("cell", "forward")


@dataclass(frozen=True)
class Replay:
    """Recorded and replayed burst means (T, M) and the RMS per trial (control steps), N."""

    model: str
    data: RecordArrays
    predicted: np.ndarray
    trials: list[int]
    rms_n: list[float]
    overall_rms_n: float
    zero_n: np.ndarray
    """(T, M) the sensor's zero added to each replayed burst, N."""
    raw_overall_rms_n: float
    """The overall RMS without the trials' zeros, N."""


def replay(records: list[TrialRecords], twin: CellConfig, model: str = "cell",
           seed: int = 0) -> Replay:
    """Replay every burst of ``records`` on the twin (``model``: ``cell`` or ``forward``).

    Raises:
        ReplayRefused: ``model="cell"`` and ``twin`` names a real robot or sensor.
        ValueError: an unknown ``model``.
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    ordered = sorted(records, key=lambda t: t.trial)
    data = to_arrays(ordered)
    arm = base_arm(twin)
    band = twin.emulator.arm.in_position_mm
    polling = polling_of(twin.robot, twin.emulator.arm)
    period = detection_period_s(data, polling.period_s)
    moved = with_true_in_position(
        data, ArmFit(arm, {n: math.inf for n in arm}, math.nan, 0, period_s=period,
                     answer_s=polling.answer_s(period)), band)
    forward = predict_means(moved, twin.emulator.sponge, arm, reading_of(twin))
    if model == "cell":
        predicted = np.full(data.mean_n.shape, np.nan)
        replayed = iter([m for means in replay_trials([t for t in ordered if t.steps], twin,
                                                      seed) for m in means])
        for i, count in enumerate(data.valid.sum(axis=1).tolist()):  # rows in record order
            predicted[i, :count] = [next(replayed) for _ in range(count)]
    else:
        predicted = forward
    drift = _drift_rate(twin) * (math.sqrt(2.0) if model == "cell" else 1.0)
    zero = sensor_zeros(ordered, data, predicted, forward, drift)
    use = data.is_step & data.has_burst
    raw = np.where(use, predicted - data.mean_n, np.nan)
    raw_finite = np.isfinite(raw)
    raw_overall = float(np.sqrt(np.mean(raw[raw_finite] ** 2))) if raw_finite.any() else math.nan
    predicted = predicted + zero
    residual = np.where(use, predicted - data.mean_n, np.nan)
    rms = [float(np.sqrt(np.nanmean(r**2))) if np.isfinite(r).any() else math.nan
           for r in residual]
    finite = np.isfinite(residual)
    overall = float(np.sqrt(np.mean(residual[finite] ** 2))) if finite.any() else math.nan
    return Replay(model, data, predicted, data.trial.tolist(), rms, overall, zero, raw_overall)


def _drift_rate(twin: CellConfig) -> float:
    """The twin's emulated sensor's bias drift along the reading's axis, N/sqrt(s)."""
    model: Any = twin.sensor_device.model(twin.emulator)
    return float(model.bias_drift_per_sqrt_s[twin.filter.axis])


def sensor_zeros(records: list[TrialRecords], data: RecordArrays, predicted: np.ndarray,
                 forward: np.ndarray, drift: float) -> np.ndarray:
    """The zero (T, M) of each burst, N: recorded minus ``predicted`` in free space, walked.

    Free space: a burst where the ``forward`` model predicts no contact. The zeros are a
    random walk at ``drift`` N/sqrt(s), 0 at each tare, fitted to those bursts alone
    (weights from the bursts' own scatter); 0 everywhere without a free-space burst.
    """
    free = data.has_burst & (np.nan_to_num(forward, nan=1.0) == 0.0) & np.isfinite(predicted)
    if not free.any():
        return np.zeros(data.mean_n.shape)
    spread = data.std_n[data.has_burst & (data.count > 1)]
    noise = float(np.nanmedian(spread)) if spread.size else 0.0
    weights = np.where(free, burst_weights(data, noise), 0.0)
    chain = build_chain(data, tare_zeros(records))
    gap = np.where(free, data.mean_n - np.where(free, predicted, 0.0), 0.0)
    return offsets(chain, solve_biases(chain, gap, weights, drift))


def write_replay(result: Replay, out: Path) -> None:
    """replay.json (RMS per trial) and replay.png (recorded vs predicted, step by step)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    (out / "replay.json").write_text(json.dumps(
        {"model": result.model, "overall_rms_n": result.overall_rms_n,
         "raw_overall_rms_n": result.raw_overall_rms_n,
         "zero_note": "each trial's sensor zero read from its free-space bursts, as a tare",
         "trials": [{"trial": t, "rms_n": r} for t, r in zip(result.trials, result.rms_n,
                                                              strict=True)]}, indent=2))
    data = result.data
    use = data.is_step & data.has_burst
    recorded = np.where(use, data.mean_n, np.nan)
    predicted = np.where(use, result.predicted, np.nan)
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    flat = np.arange(recorded.size) / recorded.shape[1] + data.trial[0]
    top.plot(flat, recorded.ravel(), ".", ms=2, label="recorded")
    label = "twin (emulated cell)" if result.model == "cell" else "twin (forward model)"
    top.plot(flat, predicted.ravel(), "-", lw=0.7, label=label)
    top.set_ylabel("force (N)")
    top.legend(fontsize=8)
    bottom.plot(result.trials, result.rms_n, "o-", ms=3)
    bottom.set_xlabel("trial")
    bottom.set_ylabel("RMS error (N)")
    figure.tight_layout()
    figure.savefig(out / "replay.png", dpi=90)
    plt.close(figure)
