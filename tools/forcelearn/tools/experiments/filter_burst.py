"""The force filter as the §5 task uses it: a move, a settle, a burst of samples, repeated.

Each path is ``MOVES`` moves. Between two moves the true normal force steps by
±``step_n`` (random sign); the move and settle take ``MOVE_S`` (the adapter's
noise forgets itself in that time), then a burst of ``burst`` samples is read
as a real JR3 adapter delivers them in sync mode: one per 1 ms turn of its main
loop, each the latest complete sensor frame (128.5 µs frames, so 7 or 8 frames
apart); the filters are told that sensor time, as the driver tells them. The samples
come from the emulator's own sensor model (its noise, the adapter's low-pass
at the cell's 125 Hz cut-off, quantisation; bias and drift off: zeroing's
job) and are scaled back to newtons as the driver does. After each burst the
estimate of each method is compared with the true force:

* ``raw``: the last sample of the burst;
* ``mean``: the plain mean of the burst;
* ``moves``: the move-aware filter (the cell's default, told of every move);
* ``stream``: the constant-rate stream filter fed sample by sample (before:
  what the task used until this filter existed, same config values).

``python -m forcelearn.tools.experiments.filter_burst`` prints the table of
docs/results/filter.md and draws its figure.
"""

from __future__ import annotations

import argparse
import itertools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from forcelearn.devices import WrenchSample
from forcelearn.emulators.jr3.sensor_model import Jr3SensorModel
from forcelearn.filtering import ForceFilter, ForceFilterConfig, MoveAwareForceFilter
from forcelearn.protocols.jr3_can.opcodes import ADAPTER_LOOP_PERIOD_S, SENSOR_FRAME_PERIOD_S
from forcelearn.protocols.jr3_can.scaling import counts_to_wrench
from forcelearn.tools.experiments.filter import quiet_drift_model

SAMPLE_PERIOD_S = ADAPTER_LOOP_PERIOD_S
"""Sync mode: the adapter answers one SYNC per 1 ms turn of its main loop."""
FRAME_S = SENSOR_FRAME_PERIOD_S
"""A sample is the latest complete sensor frame: its time is on this grid."""
CUTOFF_HZ = 125.0
"""The cell's JR3 adapter cut-off."""
MOVE_S = 0.4
"""A step's move and settle, s."""
MOVES = 20
FORCE_N = 19.61
METHODS = ("raw", "mean", "moves", "stream")
STEPS_N = (0.0, 0.3, 1.0, 2.0, 3.0)
BURSTS = (3, 10, 25, 77, 150)
DEFAULT_BURST = 25
"""Samples in the default 25 ms window: one per adapter loop turn (until 2026-12-03 the
emulator answered every SYNC, 77 samples 325 µs apart; a real adapter cannot)."""


@dataclass(frozen=True)
class BurstResult:
    """Error RMS and bias (N) of each method for one step size and burst length."""

    step_n: float
    burst: int
    rms_n: dict[str, float]
    bias_n: dict[str, float]
    noise_std_n: float


def filter_config(noise_std_n: float) -> ForceFilterConfig:
    """The cell's filter config (the example's values) for a noise of ``noise_std_n``."""
    return ForceFilterConfig(
        sample_period_s=SAMPLE_PERIOD_S,
        measurement_variance_n2=noise_std_n**2,
        noise_cutoff_hz=CUTOFF_HZ,
        axis=1,
        sign=1.0,
    )


def run(
    step_n: float, burst: int, seeds: tuple[int, ...], paths: int = 50, stream: bool = True
) -> BurstResult:
    """Errors of every method over ``paths`` paths of ``MOVES`` moves for each seed.

    ``stream=False`` leaves the (slow, sample-by-sample) stream filter out.
    """
    params = quiet_drift_model()
    full_scales = np.asarray(params.full_scales)
    noise = params.noise_std[1]
    methods = METHODS if stream else tuple(m for m in METHODS if m != "stream")
    errors: dict[str, list[float]] = {m: [] for m in methods}
    for seed in seeds:
        rng = np.random.default_rng(10_000 + seed)
        model = Jr3SensorModel(params, np.random.default_rng(seed))
        config = filter_config(noise)
        moves = MoveAwareForceFilter(config)
        tracker = ForceFilter(replace(config, model="stream"))
        for _ in range(paths):
            force = FORCE_N
            moves.reset()
            tracker.reset()
            for move in range(MOVES):
                if move:
                    force += step_n * rng.choice((-1.0, 1.0))
                    moves.on_move()
                wrench = np.array([0.0, force, 0.0, 0.0, 0.0, 0.0])
                values, dts = [], burst_steps_s(burst)
                for i, step_s in enumerate(dts):
                    counts = np.array(model.measure(wrench, MOVE_S if i == 0 else step_s,
                                                    CUTOFF_HZ))
                    values.append(float(counts_to_wrench(counts, full_scales)[1]))
                    if stream:
                        since_last = MOVE_S if i == 0 else step_s  # the move, then the burst
                        tracker.on_sample(_as_samples(values[-1:], [since_last])[0])
                estimates = {
                    "raw": values[-1],
                    "mean": float(np.mean(values)),
                    "moves": moves.on_burst(_as_samples(values, dts)),
                }
                if stream:
                    estimates["stream"] = tracker.force_n
                for method, estimate in estimates.items():
                    errors[method].append(estimate - force)
    return BurstResult(
        step_n,
        burst,
        {m: float(np.sqrt(np.mean(np.square(e)))) for m, e in errors.items()},
        {m: float(np.mean(e)) for m, e in errors.items()},
        noise,
    )


def burst_steps_s(burst: int) -> list[float]:
    """Sensor time between consecutive samples of a burst, s (the first: 0, unknown).

    Sample i is the latest sensor frame at ``i`` loop turns: frame ``floor(i x 1 ms / 128.5
    µs)``, so the steps are 7 or 8 frames (0.90 or 1.03 ms).
    """
    frames = [int(i * SAMPLE_PERIOD_S / FRAME_S + 1e-9) for i in range(burst)]
    return [0.0] + [(b - a) * FRAME_S for a, b in itertools.pairwise(frames)]


def _as_samples(values: list[float], steps_s: list[float]) -> list[WrenchSample]:
    """Wrap newtons on Fy as WrenchSamples with their sensor time.

    The filter reads the configured axis and the time between samples.
    """
    return [
        WrenchSample(np.array([0.0, v, 0.0, 0.0, 0.0, 0.0]), 0.0, i,
                     sensor_dt_s=dt if dt > 0 else None)
        for i, (v, dt) in enumerate(zip(values, steps_s, strict=True))
    ]


def table(results: list[BurstResult]) -> str:
    """Markdown table: error RMS as a multiple of the raw noise std, and bias, per method."""
    head = "| step between moves | burst | " + " | ".join(
        f"{m} RMS (× σ)" for m in METHODS
    ) + " | moves bias (N) |"
    rule = "|" + "---|" * (len(METHODS) + 3)
    lines = [head, rule]
    for r in results:
        cells = " | ".join(
            f"{r.rms_n[m] / r.noise_std_n:.2f}" if m in r.rms_n else "-" for m in METHODS
        )
        lines.append(
            f"| {r.step_n:.1f} N | {r.burst} | {cells} | {r.bias_n['moves']:+.4f} |"
        )
    return "\n".join(lines)


def plot(results: list[BurstResult], out: Path) -> Path:
    """Error RMS / σ against burst length, one line per method, for each step size."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.6))
    FigureCanvasAgg(fig)
    steps = sorted({r.step_n for r in results})
    shown = [s for s in steps if s in (0.0, 1.0, 3.0)]
    for k, step in enumerate(shown):
        ax = fig.add_subplot(1, len(shown), k + 1)
        rows = sorted((r for r in results if r.step_n == step), key=lambda r: r.burst)
        for method in (m for m in METHODS if m in rows[0].rms_n):
            ax.plot(
                [r.burst for r in rows],
                [r.rms_n[method] / r.noise_std_n for r in rows],
                marker="o",
                label=method,
            )
        ax.axhline(0.35, color="grey", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_title(f"force steps of {step:.1f} N between moves", fontsize=9)
        ax.set_xlabel("samples per burst (one per 1 ms adapter loop turn)")
        if k == 0:
            ax.set_ylabel("error RMS / raw noise σ")
            ax.legend(fontsize=8)
        ax.set_ylim(0, 1.6)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the table over step sizes and burst lengths and draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds (default 5)")
    parser.add_argument("--paths", type=int, default=50, help="paths per seed (default 50)")
    parser.add_argument("--out", type=Path, default=Path("docs/results/filter_bursts.png"))
    args = parser.parse_args(argv)
    seeds = tuple(range(args.seeds))
    results = [run(step, burst, seeds, args.paths) for step in STEPS_N for burst in BURSTS]
    print(table(results))
    print(f"figure: {plot(results, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
