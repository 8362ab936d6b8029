"""Replay a run's records on a twin: replayed against recorded force, trial by trial.

Two ways (``model``): ``"cell"`` (the default) sends the run's recorded commands to
the twin's wire-level emulated cell through the real drivers
(:mod:`forcelearn.tools.twin.replay_cell`), as CI runs the twin; ``"forward"``
predicts every burst with the fit's forward model (fast, no cell), the recorded
in-position times taken back by the twin link's mean polling latency.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

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
from forcelearn.tools.twin.forward import predict_means
from forcelearn.tools.twin.replay_cell import replay_trials
from forcelearn.tools.twin.setup import base_arm, reading_of, sponge_of

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
    if model == "cell":
        predicted = np.full(data.mean_n.shape, np.nan)
        replayed = iter([m for means in replay_trials([t for t in ordered if t.steps], twin,
                                                      seed) for m in means])
        for i, count in enumerate(data.valid.sum(axis=1).tolist()):  # rows in record order
            predicted[i, :count] = [next(replayed) for _ in range(count)]
    else:
        arm = base_arm(twin)
        band = twin.emulator.arm.in_position_mm
        polling = polling_of(twin.robot, twin.emulator.arm)
        period = detection_period_s(data, polling.period_s)
        moved = with_true_in_position(
            data, ArmFit(arm, {n: math.inf for n in arm}, math.nan, 0, period_s=period,
                         answer_s=polling.answer_s(period)), band)
        predicted = predict_means(moved, sponge_of(twin), arm, reading_of(twin))
    use = data.is_step & data.has_burst
    residual = np.where(use, predicted - data.mean_n, np.nan)
    rms = [float(np.sqrt(np.nanmean(r**2))) if np.isfinite(r).any() else math.nan
           for r in residual]
    finite = np.isfinite(residual)
    overall = float(np.sqrt(np.mean(residual[finite] ** 2))) if finite.any() else math.nan
    return Replay(model, data, predicted, data.trial.tolist(), rms, overall)


def write_replay(result: Replay, out: Path) -> None:
    """replay.json (RMS per trial) and replay.png (recorded vs predicted, step by step)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    (out / "replay.json").write_text(json.dumps(
        {"model": result.model, "overall_rms_n": result.overall_rms_n,
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
