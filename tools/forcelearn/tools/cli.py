"""The ``forcelearn`` command line: one argparse parser, one subcommand per module.

Each subcommand lives in its own module, which exposes ``add_arguments(parser)``
and ``run(args) -> int``; this file only lists them, so the command modules are
imported lazily and a broken optional part never stops ``forcelearn --version``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from importlib import metadata

from forcelearn.errors import ForcelearnError, one_line

# name -> (module implementing it, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("forcelearn.tools.commands.run", "learn force tracking on the cell (paper §5)"),
    "probe": (
        "forcelearn.tools.commands.probe",
        "find the surface (contact, stiffness) and the output map a run would use",
    ),
    "sim": ("forcelearn.tools.commands.sim", "run a simulated task (paper §4 contour tracking)"),
    "study": (
        "forcelearn.tools.commands.study",
        "sweep settings x seeds on local cores or a Dask cluster",
    ),
    "bench": (
        "forcelearn.tools.commands.bench",
        "print speed figures of the learner, link and sensor",
    ),
    "calibrate": (
        "forcelearn.tools.commands.calibrate",
        "measure sensor bias, noise and tool load",
    ),
    "check": ("forcelearn.tools.commands.check", "check a cell's devices without moving the robot"),
    "emulate": ("forcelearn.tools.commands.emulate", "serve the emulated cell on two ptys (slcan)"),
    "twin": (
        "forcelearn.tools.commands.twin",
        "fit the emulated cell to a run's records (a twin of your cell)",
    ),
    "identify": (
        "forcelearn.tools.commands.identify",
        "run a short force-guarded identification plan for the twin (timing, relaxation...)",
    ),
    "replay": (
        "forcelearn.tools.commands.replay",
        "drive a twin open-loop with a run's recorded commands; recorded vs predicted force",
    ),
    "view": (
        "forcelearn.tools.commands.view",
        "serve the read-only live page of a run directory (finished or in progress)",
    ),
}


def version() -> str:
    """Return the installed distribution's version string."""
    try:
        return metadata.version("forcelearn")
    except metadata.PackageNotFoundError:  # running from a bare source tree
        return "0+unknown"


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """Build the top-level parser; only the subcommand named in ``argv`` gets its options.

    Every subcommand is listed (with its help line from :data:`COMMANDS`), but only
    the chosen one's module is imported, so ``forcelearn --version`` or one command
    does not pay for the imports of all the others (matplotlib, filterpy, scipy).
    """
    parser = argparse.ArgumentParser(
        prog="forcelearn",
        description="Learned force control of position-controlled robots (SRV over BOXES).",
    )
    parser.add_argument("--version", action="version", version=f"forcelearn {version()}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    chosen = next((arg for arg in argv if arg in COMMANDS), None)
    for name, (module_name, help_text) in COMMANDS.items():
        command = sub.add_parser(name, help=help_text, description=help_text)
        if name == chosen:
            module = importlib.import_module(module_name)
            module.add_arguments(command)
            command.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except ForcelearnError as exc:  # one line: the message, then each note (what to check)
        print(f"forcelearn {args.command}: {one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"forcelearn {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
