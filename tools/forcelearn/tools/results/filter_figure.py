"""Figure of the force filter: raw, filtered and true force on the step-and-ramp profile.

Run ``python -m forcelearn.tools.results.filter_figure [--seed N] [--out PATH]``; writes
``docs/results/filter.png`` by default (matplotlib's Agg canvas, no pyplot) and prints the
RMS ratio and step delays of the run shown.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from forcelearn.tools.experiments import filter as filter_experiment

DEFAULT_OUT = Path("docs/results/filter.png")
ZOOMS_S = ((0.49, 0.56, "contact step, 0 -> 10 N"), (2.49, 2.58, "small step, +0.8 N (4 sigma)"))


def plot(run: filter_experiment.FilterRun, out: Path) -> Path:
    """Draw the run (full profile and two zooms) and save it as PNG."""
    fig = Figure(figsize=(9, 6.5))
    FigureCanvasAgg(fig)  # the Agg backend, without touching pyplot's global state
    grid = fig.add_gridspec(2, 2, height_ratios=(1.3, 1))
    top = fig.add_subplot(grid[0, :])
    zooms = [fig.add_subplot(grid[1, i]) for i in range(2)]
    for ax in (top, *zooms):
        ax.plot(run.t_s, run.raw_n, color="0.7", lw=0.6, label="raw (emulated JR3)")
        ax.plot(run.t_s, run.true_n, color="k", lw=1.2, ls="--", label="true")
        ax.plot(run.t_s, run.filtered_n, color="tab:red", lw=1.2, label="Kalman filtered")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("normal force Fy (N)")
        ax.grid(alpha=0.3)
    top.axhline(filter_experiment.DESIRED_N, color="tab:blue", lw=0.8, alpha=0.5,
                label="desired 19.61 N (2 kgf)")
    top.set_title(
        f"Force filter on steps and ramps: RMS error {run.filtered_rms_error_n:.3f} N = "
        f"{run.rms_ratio:.2f} x raw noise std ({run.raw_noise_std_n:.3f} N)"
    )
    top.legend(loc="upper left", fontsize=8)
    for ax, (t0, t1, title) in zip(zooms, ZOOMS_S, strict=True):
        mask = (run.t_s >= t0) & (run.t_s <= t1)
        ax.set_xlim(t0, t1)
        lo = min(run.raw_n[mask].min(), run.true_n[mask].min())
        hi = max(run.raw_n[mask].max(), run.true_n[mask].max())
        ax.set_ylim(lo - 0.2, hi + 0.2)
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the experiment, save the figure, print its figures of merit."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="sensor noise seed")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="PNG to write")
    args = parser.parse_args(argv)
    run = filter_experiment.run(args.seed)
    path = plot(run, args.out)
    delays = ", ".join(f"{1000 * d:.0f}" for d in run.step_delays_s)
    print(f"seed {args.seed}: RMS ratio {run.rms_ratio:.3f}, step delays {delays} ms -> {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
