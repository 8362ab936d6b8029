"""The path task's acceptance study: every example part, over both cells, several seeds.

::

    nice -n 10 python -m forcelearn.tools.path_study --out runs/path-study          # all
    python -m forcelearn.tools.path_study --cells link-jr3 --parts cylinder --seeds 2 --out D
    python -m forcelearn.tools.path_study --table runs/path-study                   # reprint

Each run is ``forcelearn run`` of an example config of ``examples/paths/`` (the
part's ``*-cell.toml``), on the computer link + JR3 as written, or over EGM +
Net F/T (the robot, sensor, filter and calibration of
``cylinder-egm-netft-cell.toml``). One process, runs one after the other; each
run's summary is appended to ``results.csv`` as it ends, so a partial study
still says something, and the table (docs/path.md) is printed from that file:

==========================  ====================================================
in band at end              runs whose last 5 passes were all complete and in band
warm start in band by 5     runs whose first pass in band was among passes 0-4
final RMS %                 the final force RMS (median of the last 5 passes), % of
                            the desired force: median and worst over the seeds
largest offset              the largest |offset| a pressing move commanded, mm
outside workspace           steps whose commanded pose lay outside the workspace
contact lost                contact-loss events (the gap part: its slot's points)
==========================  ====================================================
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from forcelearn.site import CellConfig, load_cell_config
from forcelearn.tools.experiments.path_run import run_path

PARTS = {
    "cylinder": "cylinder-cell.toml",
    "cylinder-rapid": "cylinder-rapid-cell.toml",
    "sphere": "sphere-cell.toml",
    "heightmap": "heightmap-cell.toml",
    "gap": "gap-cell.toml",
}
"""Study part name -> its example config in examples/paths/."""
CELLS = ("link-jr3", "egm-netft")
EGM_CELL = "cylinder-egm-netft-cell.toml"
"""The example whose robot, sensor, filter and calibration make the EGM + Net F/T cell."""
COLUMNS = ("cell", "part", "seed", "passes", "in_band_at_end", "first_pass_in_band",
           "warm_start_in_band_within_5", "final_force_rms_pct", "largest_offset_mm",
           "max_deviation_mm", "moves_outside_workspace", "moves_beyond_max_deviation",
           "contact_lost_count", "contact_lost_points", "failures", "wall_s", "error")


def examples_dir() -> Path:
    """examples/paths beside the source tree, else ./examples/paths."""
    here = Path(__file__).resolve().parents[3] / "examples" / "paths"
    return here if here.is_dir() else Path("examples/paths")


def study_config(part: str, cell: str, folder: Path) -> CellConfig:
    """The part's example config on ``cell``."""
    config = load_cell_config(folder / PARTS[part])
    if cell == "link-jr3":
        return config
    other = load_cell_config(folder / EGM_CELL)
    return replace(config, robot=other.robot, sensor=other.sensor, bus=other.bus,
                   filter=other.filter, calibration_file=other.calibration_file,
                   emulator=replace(config.emulator, devices=other.emulator.devices))


def run_one(part: str, cell: str, seed: int, passes: int, out: Path) -> dict[str, Any]:
    """One run; its row of results.csv (an error is recorded, not raised)."""
    row: dict[str, Any] = {"cell": cell, "part": part, "seed": seed, "passes": passes}
    try:
        config = study_config(part, cell, examples_dir())
        summary = run_path(config, out / cell / part / f"seed{seed}", passes, seed,
                           figures=seed == 0)
    except Exception as exc:  # a study records a run that failed and goes on
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    row.update({key: summary.get(key, "") for key in COLUMNS if key in summary})
    row["contact_lost_points"] = " ".join(str(p) for p in summary["contact_lost_points"])
    row["error"] = ""
    return row


def append(path: Path, row: dict[str, Any]) -> None:
    """Append a row to results.csv (the header first if the file is new)."""
    new = not path.exists()
    with path.open("a", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS, extrasaction="ignore")
        if new:
            writer.writeheader()
        writer.writerow(row)


def table(path: Path) -> str:
    """The acceptance table (markdown) of a results.csv."""
    rows = list(csv.DictReader(path.open(encoding="utf-8")))
    groups: dict[tuple[str, str], list[dict[str, str]]] = {}
    for row in rows:
        groups.setdefault((row["cell"], row["part"]), []).append(row)
    lines = ["| cell | part | seeds | in band at end | warm start in band by pass 5 | final RMS % "
             "median (worst) | largest offset / max_deviation mm | outside workspace | "
             "contact lost | errors |", "|" + "---|" * 10]
    for (cell, part), group in groups.items():
        done = [r for r in group if not r["error"]]
        rms = [float(r["final_force_rms_pct"]) for r in done]
        offsets = [float(r["largest_offset_mm"]) for r in done]
        lines.append(
            f"| {cell} | {part} | {len(group)} | "
            f"{sum(r['in_band_at_end'] == 'True' for r in done)}/{len(group)} | "
            f"{sum(r['warm_start_in_band_within_5'] == 'True' for r in done)}/{len(group)} | "
            + (f"{statistics.median(rms):.2f} ({max(rms):.2f}) | " if rms else "- | ")
            + (f"{max(offsets):.2f} / {done[0]['max_deviation_mm']} | " if done else "- | ")
            + f"{sum(int(r['moves_outside_workspace']) for r in done)} | "
            + f"{sum(int(r['contact_lost_count']) for r in done)} | "
            + f"{len(group) - len(done)} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the study (or reprint its table with ``--table``)."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.path_study",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--out", type=Path, help="study folder (results.csv, run directories)")
    parser.add_argument("--cells", default=",".join(CELLS), help=f"of {', '.join(CELLS)}")
    parser.add_argument("--parts", default=",".join(PARTS), help=f"of {', '.join(PARTS)}")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--first-seed", type=int, default=0,
                        help="seeds first-seed .. first-seed + seeds - 1 (to extend a study)")
    parser.add_argument("--passes", type=int, default=25)
    parser.add_argument("--table", type=Path, metavar="DIR", help="print the table of DIR")
    args = parser.parse_args(argv)
    if args.table is not None:
        print(table(args.table / "results.csv"))
        return 0
    if args.out is None:
        parser.error("give --out DIR (or --table DIR)")
    cells, parts = args.cells.split(","), args.parts.split(",")
    unknown = [c for c in cells if c not in CELLS] + [p for p in parts if p not in PARTS]
    if unknown:
        parser.error(f"unknown cell or part: {', '.join(unknown)}")
    args.out.mkdir(parents=True, exist_ok=True)
    results = args.out / "results.csv"
    for cell in cells:
        for part in parts:
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                started = time.perf_counter()
                row = run_one(part, cell, seed, args.passes, args.out)
                append(results, row)
                verdict = row["error"] or (
                    f"in band {row.get('in_band_at_end')}, first in band "
                    f"{row.get('first_pass_in_band')}, final RMS "
                    f"{float(row.get('final_force_rms_pct', 'nan')):.2f} %")
                print(f"{cell} {part} seed {seed}: {verdict} "
                      f"({time.perf_counter() - started:.0f} s)", file=sys.stderr, flush=True)
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
