"""Replay a run's records on a twin: predicted against recorded force, trial by trial."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from forcelearn.records import TrialRecords
from forcelearn.site.config import CellConfig
from forcelearn.tools.twin.arrays import RecordArrays, to_arrays
from forcelearn.tools.twin.forward import predict_means
from forcelearn.tools.twin.setup import base_arm, reading_of, sponge_of


@dataclass(frozen=True)
class Replay:
    """Recorded and predicted burst means (T, M) and the RMS per trial (control steps), N."""

    data: RecordArrays
    predicted: np.ndarray
    trials: list[int]
    rms_n: list[float]
    overall_rms_n: float


def replay(records: list[TrialRecords], twin: CellConfig) -> Replay:
    """Predict every burst of ``records`` with the twin's sponge and arm."""
    data = to_arrays(sorted(records, key=lambda t: t.trial))
    arm = base_arm(twin)
    predicted = predict_means(data, sponge_of(twin), arm, reading_of(twin))
    use = data.is_step & data.has_burst
    residual = np.where(use, predicted - data.mean_n, np.nan)
    rms = [float(np.sqrt(np.nanmean(r**2))) if np.isfinite(r).any() else math.nan
           for r in residual]
    overall = float(np.sqrt(np.nanmean(residual**2))) if use.any() else math.nan
    return Replay(data, predicted, data.trial.tolist(), rms, overall)


def write_replay(result: Replay, out: Path) -> None:
    """replay.json (RMS per trial) and replay.png (recorded vs predicted, step by step)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    (out / "replay.json").write_text(json.dumps(
        {"overall_rms_n": result.overall_rms_n,
         "trials": [{"trial": t, "rms_n": r} for t, r in zip(result.trials, result.rms_n,
                                                              strict=True)]}, indent=2))
    data = result.data
    use = data.is_step & data.has_burst
    recorded = np.where(use, data.mean_n, np.nan)
    predicted = np.where(use, result.predicted, np.nan)
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    flat = np.arange(recorded.size) / recorded.shape[1] + data.trial[0]
    top.plot(flat, recorded.ravel(), ".", ms=2, label="recorded")
    top.plot(flat, predicted.ravel(), "-", lw=0.7, label="twin")
    top.set_ylabel("force (N)")
    top.legend(fontsize=8)
    bottom.plot(result.trials, result.rms_n, "o-", ms=3)
    bottom.set_xlabel("trial")
    bottom.set_ylabel("RMS error (N)")
    figure.tight_layout()
    figure.savefig(out / "replay.png", dpi=90)
    plt.close(figure)
