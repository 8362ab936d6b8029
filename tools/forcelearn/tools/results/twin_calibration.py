"""Are the twin's sigmas honest? Its determined values' deviations from the truth, pooled.

Over many hidden cells a twin whose 1-sigma is right puts about 4.6 % of its determined
values beyond 2 sigma of the truth and 0.27 % beyond 3 sigma, with a mean squared
deviation (z^2) of 1; a parameter whose mean z is far from 0 is biased. This module
counts them per parameter, over one study or several
(``python -m forcelearn.tools.results.twin_calibration STUDY_DIR ...``).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from forcelearn.tools.results.twin_compare import load_json
from forcelearn.tools.results.twin_identified import Deviation, deviations


def beyond_share(sigmas: float) -> float:
    """The share of a standard normal's draws more than ``sigmas`` from 0."""
    return math.erfc(sigmas / math.sqrt(2.0))


@dataclass(frozen=True)
class Calibration:
    """Deviations of one parameter (or all) pooled over cells."""

    name: str
    z: tuple[float, ...]

    @property
    def count(self) -> int:
        """How many determined values."""
        return len(self.z)

    @property
    def mean_z(self) -> float:
        """Mean deviation in sigmas: a bias when far from 0 (its own sigma is 1/sqrt(n))."""
        return sum(self.z) / self.count

    @property
    def mean_z2(self) -> float:
        """Mean squared deviation: 1 for honest sigmas, above for too small ones."""
        return sum(z * z for z in self.z) / self.count

    def beyond(self, sigmas: float) -> int:
        """How many deviations exceed ``sigmas``."""
        return sum(abs(z) > sigmas for z in self.z)

    def expected(self, sigmas: float) -> float:
        """How many a standard normal puts beyond ``sigmas`` among ``count``."""
        return self.count * beyond_share(sigmas)


def study_deviations(out: Path, cells: Sequence[str] | None = None) -> list[Deviation]:
    """The deviations of a study folder's fitted ``cells`` (default: every cell-XX folder).

    Cells without a twin.json or a truth are skipped.
    """
    names = cells if cells is not None else sorted(p.name for p in out.glob("cell-*")
                                                   if p.is_dir())
    found: list[Deviation] = []
    for cell in names:
        twin_json = out / cell / "twin" / "twin.json"
        truth = out / "cells" / f"{cell}.truth.json"
        if twin_json.exists() and truth.exists():
            found.extend(deviations(load_json(truth), load_json(twin_json)))
    return found


def calibrations(found: Iterable[Deviation]) -> list[Calibration]:
    """One row for all values, then one per parameter, most values first."""
    by: dict[str, list[float]] = {}
    every: list[float] = []
    for d in found:
        by.setdefault(d.name, []).append(d.z)
        every.append(d.z)
    rows = [Calibration(name, tuple(z)) for name, z in by.items()]
    rows.sort(key=lambda c: (-c.count, c.name))
    return ([Calibration("all", tuple(every))] if every else []) + rows


def calibration_lines(rows: Sequence[Calibration]) -> list[str]:
    """A markdown table of the calibration rows."""
    if not rows:
        return ["No determined value with a truth to compare."]
    lines = ["| parameter | determined | mean z | mean z^2 | beyond 2 sigma (normal) "
             "| beyond 3 sigma (normal) |", "|---|---|---|---|---|---|"]
    for c in rows:
        lines.append(f"| {c.name} | {c.count} | {c.mean_z:+.2f} | {c.mean_z2:.2f} | "
                     f"{c.beyond(2.0)} ({c.expected(2.0):.1f}) | "
                     f"{c.beyond(3.0)} ({c.expected(3.0):.1f}) |")
    return lines


def page_lines(out: Path, cells: Sequence[str]) -> list[str]:
    """The study page's section on the sigmas' calibration."""
    return ["## Are the sigmas honest?", "",
            "Every value the twin reports determined, against the cell's truth in its own "
            "sigmas (z). Honest sigmas give a mean z near 0 (within about 1/sqrt(n)), a mean "
            "z^2 near 1 and, in brackets, the counts a normal distribution expects beyond 2 "
            "and 3 sigma.", "", *calibration_lines(calibrations(study_deviations(out, cells))), ""]


def main(argv: Sequence[str] | None = None) -> int:
    """Print the pooled calibration of one or more study folders."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("studies", nargs="+", type=Path, help="hidden-cell study folders")
    args = parser.parse_args(argv)
    missing = [str(p) for p in args.studies if not (p / "cells").is_dir()]
    if missing:
        parser.error(f"not a hidden-cell study folder (no cells/): {', '.join(missing)}")
    found = [d for study in args.studies for d in study_deviations(study)]
    print("\n".join(calibration_lines(calibrations(found))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
