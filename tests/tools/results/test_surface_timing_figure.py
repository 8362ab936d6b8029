"""The timing study's figure and table (docs/results/surface-timing.md) from a tiny fake study."""

import json
from pathlib import Path
from typing import Any

import pytest

from forcelearn.errors import StudyError
from forcelearn.tools.results import surface_timing

KEYS = ["emulator.arm.lag_s", "emulator.arm.default_speed_mm_s", "robot.baudrate"]


def _row(seed: int, lag: str, speed: str, baud: str, converged: int | None) -> dict[str, Any]:
    return {
        "run_id": f"{lag}-{speed}-{baud}-{seed}",
        "seed": seed,
        KEYS[0]: lag,
        KEYS[1]: speed,
        KEYS[2]: baud,
        "converged_trial": converged,
        "final_force_rms_n": 0.1 * (seed + 1) + float(lag),
        "failures": seed,
        "trials_out_of_band_after_convergence": None if converged is None else 2 * seed,
        "cell_time_s": 3600.0 * float(lag) * 10 + 7200.0 * (baud == "4800"),
    }


def _write_study(folder: Path, rows: list[dict[str, Any]], keys: list[str] = KEYS) -> Path:
    (folder / "runs").mkdir(parents=True)
    points = sorted({tuple(r[k] for k in keys) for r in rows})
    manifest = {
        "task": "surface",
        "trials": 50,
        "seeds": sorted({r["seed"] for r in rows}),
        "keys": keys,
        "points": [dict(zip(keys, p, strict=True)) for p in points],
    }
    (folder / "study.json").write_text(json.dumps(manifest))
    for row in rows:
        (folder / "runs" / f"{row['run_id']}.json").write_text(json.dumps(row))
    return folder


def _grid() -> list[dict[str, Any]]:
    rows = []
    for lag in ("0.01", "0.2"):
        for speed in ("100", "20"):  # written out of order: the figure sorts by value
            for baud in ("4800", "9600"):
                for seed in (0, 1):
                    converged: int | None = 10 + seed
                    if (lag, speed, baud, seed) == ("0.2", "20", "4800", 1):
                        converged = None  # never converged: counts as the 50-trial budget
                    rows.append(_row(seed, lag, speed, baud, converged))
    return rows


def test_figure_and_table_from_a_fake_study(tmp_path: Path) -> None:
    """Medians over seeds per point (never converged = the budget), one row per point."""
    study = _write_study(tmp_path / "grid", _grid())
    out = tmp_path / "fig" / "timing.png"
    assert surface_timing.main([str(study), "--out", str(out)]) == 0
    assert out.read_bytes().startswith(b"\x89PNG")

    keys, trials, rows = surface_timing.load_study(study)
    assert keys == KEYS and trials == 50 and len(rows) == 16
    grid, notes = surface_timing.panel(keys, trials, rows, "converged_trial", "4800")
    # rows: lag 0.01, 0.2; columns: speed 20, 100 (ascending, not as written)
    assert grid == [[10.5, 10.5], [30.0, 10.5]]
    assert notes[1][0] == "30\n1/2 conv."
    hours, _ = surface_timing.panel(keys, trials, rows, "cell_time_h", "4800")
    assert hours == [[pytest.approx(2.1), pytest.approx(2.1)], [4.0, 4.0]]
    rms, _ = surface_timing.panel(keys, trials, rows, "final_force_rms_n", "9600")
    assert rms[0][0] == pytest.approx(0.16)

    lines = surface_timing.table(keys, trials, rows)
    assert len(lines) == 2 + 8
    assert lines[2].startswith("| 0.01 | 20 | 4800 | 2 / 2 | 10, 11 | 0.110, 0.210 | 0, 1 | 0, 2 |")
    assert "| 0.2 | 20 | 4800 | 1 / 2 | 10, – |" in lines[6]


def test_an_unfinished_or_other_study_is_refused(tmp_path: Path) -> None:
    """Missing runs, a two-key sweep or an empty folder raise StudyError saying what to do."""
    rows = _grid()
    study = _write_study(tmp_path / "partial", rows)
    (study / "runs" / f"{rows[0]['run_id']}.json").unlink()
    with pytest.raises(StudyError, match="15 of the study's 16 runs"):
        surface_timing.load_study(study)
    two = _write_study(tmp_path / "two", [_row(0, "0.01", "20", "9600", 5)], keys=KEYS[:2])
    with pytest.raises(StudyError, match="sweeps 2 keys"):
        surface_timing.load_study(two)
    with pytest.raises(StudyError, match=r"no study\.json"):
        surface_timing.load_study(tmp_path)
