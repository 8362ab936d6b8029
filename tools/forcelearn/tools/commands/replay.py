"""``forcelearn replay RUN_DIR --on twin.toml``: a run's recorded commands on a twin, open loop.

Every recorded move and burst of the run is predicted by the twin's physics
(the forward model of ``forcelearn twin``, with twin.toml's sponge and arm:
the same law as the emulated sponge, driven by the recorded poses and times),
and the recorded force is plotted against the prediction trial by trial. The
RMS per trial and overall are printed (control steps only).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Attach the command's options."""
    parser.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="the run to replay")
    parser.add_argument("--on", type=Path, required=True, dest="twin",
                        help="the twin's config (forcelearn twin --out)")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder for replay.png and replay.json (default: RUN_DIR)")


def run(args: argparse.Namespace) -> int:
    """Replay, print the RMS per trial and overall, write the figure."""
    from forcelearn.site.config import load_cell_config
    from forcelearn.tools.twin.replay import replay, write_replay
    from forcelearn.tools.twin.source import read_runs

    source = read_runs([args.run_dir])
    twin = load_cell_config(args.twin)
    result = replay(source.records, twin)
    out = args.out or args.run_dir
    write_replay(result, out)
    for trial, rms in zip(result.trials, result.rms_n, strict=True):
        print(f"trial {trial:4d}  RMS {rms:.3f} N")
    print(f"overall RMS {result.overall_rms_n:.3f} N over {len(result.trials)} trials; "
          f"wrote {out / 'replay.png'}")
    return 0
