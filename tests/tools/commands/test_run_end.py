"""What `forcelearn run` prints at its end: a few lines for a person, or the summary for scripts."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from forcelearn.tools.cli import main
from forcelearn.tools.experiments.surface_outputs import FIGURES, end_lines
from forcelearn.trainer import CONVERGENCE_WINDOW


def test_a_run_ends_with_a_few_lines_and_json_prints_the_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], configured_map_toml: str
) -> None:
    """Two trials end with the verdict, the force against the band, the diagnosis, the folder.

    A resume with --json then prints exactly summary.json on stdout.
    """
    config = tmp_path / "cell.toml"
    config.write_text(configured_map_toml)  # no probe: two short trials
    out = tmp_path / "run"
    argv = ["run", "--config", str(config), "--out", str(out), "--trials", "2", "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr()
    lines = printed.out.splitlines()
    summary = json.loads((out / "summary.json").read_text())
    assert len(lines) <= 8
    assert lines[0].endswith(f"failed trials: {summary['failures']}")
    assert lines[1].startswith("not converged in 2 trials; NOT in band at the end")
    assert f"{summary['final_force_rms_n']:.3f} N against the band" in lines[2]
    assert f"diagnosis: {summary['diagnosis']}" in lines
    assert f"run directory: {out}" in lines
    figures = next(line for line in lines if "figures:" in line)
    assert all((out / name).exists() for name in figures.split(": ")[1].split(", "))
    assert "output_map" not in printed.out  # the summary's internals stay in the file
    assert "NOT CONVERGED" in printed.err.splitlines()[-1]

    assert main(["run", "--resume", str(out), "--trials", "3", "--no-progress", "--json"]) == 0
    printed = capsys.readouterr()
    assert json.loads(printed.out) == json.loads((out / "summary.json").read_text())
    assert json.loads(printed.out)["trials"] == 3
    assert printed.err.splitlines()[-1].endswith(json.loads(printed.out)["diagnosis"])


def test_a_run_that_ended_in_band_names_no_diagnosis(tmp_path: Path) -> None:
    """Converged and in band: the lines say so, with no diagnosis; NaN RMS reads as none."""
    summary = {
        "trials": 40, "failures": 0, "seed": 3, "learner_start": "cold", "converged_trial": 7,
        "in_band_at_end": True, "desired_force_n": 20.0, "final_force_rms_n": 0.25,
        "diagnosis": None,
    }
    (tmp_path / FIGURES[0]).write_bytes(b"")
    lines = end_lines(summary, tmp_path)
    assert lines[0] == "40 trials, seed 3, cold start; failed trials: 0"
    window = CONVERGENCE_WINDOW
    assert lines[1] == f"converged at trial 7; in band at the end (the last {window} trials)"
    assert not any(line.startswith("diagnosis") for line in lines)
    assert f"  figures: {FIGURES[0]}" in lines
    nan = end_lines({**summary, "final_force_rms_n": float("nan")}, tmp_path)
    assert "final force RMS none (no step)" in nan[2]
