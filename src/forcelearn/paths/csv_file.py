"""A taught path as CSV: one pose a row, ``x_mm,y_mm,z_mm,qw,qx,qy,qz[,name]``.

The header is optional; when present it names the columns (any order, ``name``
optional). Without it the columns are in that order. Blank lines and lines
starting with ``#`` are skipped. Poses are in the robot's base frame.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from forcelearn.errors import PathParseError
from forcelearn.paths.taught import TaughtPath

COLUMNS = ("x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz")
NAME_COLUMN = "name"


def read_path_csv(path: str | Path) -> TaughtPath:
    """Read a taught path from a CSV file; raises :class:`PathParseError` naming the line."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise PathParseError(source, 0, f"cannot read the path file: {exc}") from exc
    return parse_path_csv(text, source)


def parse_path_csv(text: str, source: str = "<csv>") -> TaughtPath:
    """Parse CSV text (see the module docstring); ``source`` names it in errors."""
    rows = [
        (number, row)
        for number, row in enumerate(csv.reader(io.StringIO(text)), start=1)
        if row and "".join(row).strip() and not row[0].lstrip().startswith("#")
    ]
    order: list[int] = list(range(len(COLUMNS)))
    name_at: int | None = len(COLUMNS)
    widths: tuple[int, ...] = (len(COLUMNS), len(COLUMNS) + 1)
    if rows and not _is_number(rows[0][1][0]):
        number, header = rows.pop(0)
        order, name_at = _columns(header, source, number)
        widths = (len(header),)
    positions, quaternions, names, lines = [], [], [], []
    for number, row in rows:
        cells = [cell.strip() for cell in row]
        if len(cells) not in widths:
            raise PathParseError(source, number, f"expected the columns {','.join(COLUMNS)}"
                                 f"[,{NAME_COLUMN}], got {len(cells)} fields")
        try:
            values = [float(cells[i]) for i in order]
        except ValueError as exc:
            raise PathParseError(source, number, f"not a number: {exc}") from exc
        if not np.all(np.isfinite(values)):
            raise PathParseError(source, number, "a value is not finite")
        positions.append(values[:3])
        quaternions.append(values[3:])
        names.append(cells[name_at] if name_at is not None and name_at < len(cells) else "")
        lines.append(number)
    if not positions:
        raise PathParseError(source, 0, "the file holds no pose")
    return TaughtPath(np.array(positions), np.array(quaternions), tuple(names), tuple(lines),
                      source=source, instructions=("CSV",) * len(lines))


def write_path_csv(path: str | Path, taught: TaughtPath) -> None:
    """Write a path as CSV with a header (and the names when any pose has one)."""
    Path(path).write_text(format_path_csv(taught), encoding="utf-8")


def format_path_csv(taught: TaughtPath) -> str:
    """The CSV text of a path; floats written with ``repr`` so they read back exactly."""
    with_names = any(taught.names)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*COLUMNS, *([NAME_COLUMN] if with_names else [])])
    for i in range(len(taught)):
        values = [repr(float(v)) for v in (*taught.positions_mm[i], *taught.quaternions_wxyz[i])]
        writer.writerow([*values, *([taught.names[i]] if with_names else [])])
    return out.getvalue()


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _columns(header: list[str], source: str, line: int) -> tuple[list[int], int | None]:
    names = [cell.strip().lower() for cell in header]
    missing = [column for column in COLUMNS if column not in names]
    unknown = [name for name in names if name not in (*COLUMNS, NAME_COLUMN)]
    if missing or unknown:
        raise PathParseError(source, line, f"header must name {','.join(COLUMNS)} (and "
                             f"optionally {NAME_COLUMN}); missing {missing}, unknown {unknown}")
    return [names.index(c) for c in COLUMNS], (
        names.index(NAME_COLUMN) if NAME_COLUMN in names else None
    )
