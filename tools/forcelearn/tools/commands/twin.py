"""``forcelearn twin RUN_DIR [RUN_DIR...] --out twin.toml``: fit the emulated cell to a run.

``--identification DIR`` adds a ``forcelearn identify`` run (the arm's timing from its
polled moves; its press, hold and cycles as fitted records).

Writes twin.toml (an emulated-cell config: ``forcelearn run --config twin.toml``),
twin.md, twin.json and twin_heldout.png beside it. When no member of the model
family explains the records, says "this cell is not represented by the twin",
writes the report but no twin.toml, and exits 3. docs/twin.md.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

EXIT_NOT_REPRESENTED = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Attach the command's options."""
    parser.add_argument("run_dirs", nargs="+", type=Path, metavar="RUN_DIR",
                        help="run directories of one cell (taken in the order given)")
    parser.add_argument("--calibration", type=Path, default=None,
                        help="a forcelearn calibrate file: its measured noise is used")
    parser.add_argument("--identification", type=Path, default=None, metavar="DIR",
                        help="a forcelearn identify folder: its polled moves give the arm, its "
                             "press, hold and cycles join the fit")
    parser.add_argument("--out", type=Path, required=True,
                        help="the twin's config to write (twin.md, twin.json beside it)")
    parser.add_argument("--no-figure", action="store_true",
                        help="write no twin_heldout.png (a study's fits: twin.json is enough)")


def run(args: argparse.Namespace) -> int:
    """Fit, report, and write the twin if the records are represented."""
    from forcelearn.calibration.file_format import load_calibration
    from forcelearn.emulators.physics.arm import ArmConfig
    from forcelearn.tools.twin.arm import polling_of
    from forcelearn.tools.twin.fit import fit_twin
    from forcelearn.tools.twin.identify import read_identification
    from forcelearn.tools.twin.report import write_report
    from forcelearn.tools.twin.setup import base_arm, base_sponge, configured_colour, reading_of
    from forcelearn.tools.twin.source import read_runs

    source = read_runs(list(args.run_dirs))
    config = source.config
    noise = None
    if args.calibration is not None:
        noise = float(load_calibration(args.calibration).noise.std[config.filter.axis])
    identification = (read_identification(args.identification)
                      if args.identification is not None else None)
    arm = ArmConfig()  # the controller's defaults: the run's [emulator.arm] never reaches it
    fit = fit_twin(source.records, base_sponge(config), base_arm(), reading_of(config),
                   arm.in_position_mm, arm.tick_s, noise,
                   configured_phi=configured_colour(config, source.records),
                   polling=polling_of(config.robot, arm), identification=identification)
    document = write_report(fit, source, args.out, figure=not args.no_figure)
    folder = args.out.parent
    if not fit.represented:
        print(f"this cell is not represented by the twin: {fit.reason}")
        print(f"report: {folder / 'twin.md'} (no {args.out} written)")
        return EXIT_NOT_REPRESENTED
    undetermined = [p["name"] for p in document["parameters"] if not p["determined"]]
    print(f"twin: member {fit.chosen.member.name}; held-out RMS "
          f"{fit.chosen.heldout_rms_n:.3f} N (bar {fit.threshold_n:.3f} N)")
    if undetermined:
        print(f"not determined by the records: {', '.join(undetermined)} (see twin.md)")
    arm_rms = fit.arm.rms_s
    if math.isfinite(arm_rms):
        print(f"arm timing RMS {arm_rms * 1000:.1f} ms over {fit.arm.moves} moves")
    print(f"wrote {args.out}, {folder / 'twin.md'}, {folder / 'twin.json'}")
    return 0
