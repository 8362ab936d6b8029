"""``forcelearn replay RUN_DIR --on twin.toml``: a run's recorded commands on a twin, open loop.

By default the run's recorded commands (probe, approach, steps, retreat, tares,
each burst's sample count) are sent in order to twin.toml's wire-level emulated
cell through the same drivers and safety limits as a run (only an emulated cell:
a config naming a real robot or sensor is refused); ``--model forward`` predicts
with the fit's forward model instead (fast, no cell). The recorded force is
plotted against the replayed one trial by trial; the RMS per trial and overall
are printed (control steps only).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Attach the command's options."""
    parser.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="the run to replay")
    parser.add_argument("--on", type=Path, required=True, dest="twin",
                        help="the twin's config (forcelearn twin --out)")
    parser.add_argument("--model", choices=("cell", "forward"), default="cell",
                        help="cell: drive the twin's emulated cell (default); forward: the "
                             "fit's forward model (fast)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the emulated sensor's noise (--model cell)")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder for replay.png and replay.json (default: RUN_DIR)")


def run(args: argparse.Namespace) -> int:
    """Replay, print the RMS per trial and overall, write the figure."""
    from forcelearn.site.config import load_cell_config
    from forcelearn.tools.twin.replay import replay, write_replay
    from forcelearn.tools.twin.source import read_runs

    source = read_runs([args.run_dir])
    twin = load_cell_config(args.twin)
    result = replay(source.records, twin, args.model, args.seed)
    out = args.out or args.run_dir
    write_replay(result, out)
    for trial, rms in zip(result.trials, result.rms_n, strict=True):
        print(f"trial {trial:4d}  RMS {rms:.3f} N")
    print(f"overall RMS {result.overall_rms_n:.3f} N over {len(result.trials)} trials "
          f"({args.model}; each trial's sensor zero read from its free-space bursts, as a "
          f"tare would: {result.raw_overall_rms_n:.3f} N without); "
          f"wrote {out / 'replay.png'}")
    return 0
