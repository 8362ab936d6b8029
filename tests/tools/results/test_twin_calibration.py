"""The sigmas' calibration over hidden cells: deviations pooled, counted against a normal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from forcelearn.tools.results.twin_calibration import (
    beyond_share,
    calibrations,
    main,
    study_deviations,
)
from forcelearn.tools.results.twin_identified import Deviation


def _write_cell(out: Path, cell: str, stiffness: float, sigma: float, determined: bool = True
                ) -> None:
    (out / "cells").mkdir(parents=True, exist_ok=True)
    truth = {"sponge": {"stiffness_n_per_mm": 2.0}, "arm": {"lag_s": 0.05},
             "sensor": {"noise_n": 0.2}}
    (out / "cells" / f"{cell}.truth.json").write_text(json.dumps(truth))
    rows = [{"name": "stiffness_n_per_mm", "value": stiffness, "sigma": sigma,
             "determined": determined},
            {"name": "start_delay_s", "value": 9.0, "sigma": 0.001, "determined": True}]
    (out / cell / "twin").mkdir(parents=True)
    (out / cell / "twin" / "twin.json").write_text(json.dumps({"parameters": rows}))


def test_a_normal_share_beyond_two_and_three_sigma() -> None:
    """4.55 % and 0.27 %."""
    assert beyond_share(2.0) == pytest.approx(0.0455, abs=1e-4)
    assert beyond_share(3.0) == pytest.approx(0.0027, abs=1e-4)


def test_honest_sigmas_give_mean_z2_near_one_and_the_normal_counts() -> None:
    """Deviations drawn with their stated sigma: mean z^2 ~ 1, bias ~ 0; doubled ones read 4."""
    rng = np.random.default_rng(7)
    draws = rng.normal(0.0, 1.0, 20_000)
    honest = calibrations(Deviation("k", 2.0 + 0.1 * z, 0.1, 2.0) for z in draws)[0]
    assert honest.mean_z2 == pytest.approx(1.0, abs=0.05)
    assert abs(honest.mean_z) < 0.05
    assert honest.beyond(3.0) == pytest.approx(honest.expected(3.0), rel=0.35)
    too_small = calibrations(Deviation("k", 2.0 + 0.2 * z, 0.1, 2.0) for z in draws)[0]
    assert too_small.mean_z2 == pytest.approx(4.0, rel=0.05)


def test_a_study_counts_only_determined_compared_values(tmp_path: Path) -> None:
    """Undetermined values and the parameters not compared (the link's start delay) are out."""
    _write_cell(tmp_path, "cell-01", 2.3, 0.1)
    _write_cell(tmp_path, "cell-02", 1.9, 0.1)
    _write_cell(tmp_path, "cell-03", 5.0, 0.1, determined=False)
    found = study_deviations(tmp_path)
    assert [d.name for d in found] == ["stiffness_n_per_mm"] * 2
    rows = calibrations(found)
    assert [r.name for r in rows] == ["all", "stiffness_n_per_mm"]
    assert rows[0].beyond(2.0) == 1 and rows[0].mean_z == pytest.approx(1.0)
    assert study_deviations(tmp_path, ["cell-02"])[0].z == pytest.approx(-1.0)


def test_the_command_pools_studies_and_refuses_other_folders(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two studies' cells in one table; a folder without cells/ is a usage error."""
    _write_cell(tmp_path / "a", "cell-01", 2.25, 0.1)
    _write_cell(tmp_path / "b", "cell-01", 1.75, 0.1)
    assert main([str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    table = capsys.readouterr().out
    assert "| all | 2 |" in table and "| 6.25 | 2 (0.1) | 0 (0.0) |" in table
    with pytest.raises(SystemExit):
        main([str(tmp_path)])
    assert "not a hidden-cell study folder" in capsys.readouterr().err
