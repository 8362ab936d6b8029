"""``forcelearn twin`` and ``forcelearn replay`` on records made by the emulator's physics."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import Sponge, SpongeParams
from forcelearn.records import TrialRecords
from forcelearn.site.config import load_cell_config
from forcelearn.site.jr3_kind import sensor_model
from forcelearn.tools import cli
from forcelearn.tools.twin import source
from forcelearn.tools.twin.arrays import RecordsError
from forcelearn.tools.twin.simulate import SimulatedRun, noise_only_sensor, simulate_run

NOISY = noise_only_sensor(0.1)
TRUTH = SpongeParams(stiffness_n_per_mm=2.6, surface_y_mm=0.5, relaxation_ratio=0.3)


def _serve(monkeypatch: pytest.MonkeyPatch, records: list[TrialRecords]) -> None:
    monkeypatch.setattr(source, "read_run_records", lambda run_dir: records)


@pytest.fixture(scope="module")
def records() -> list[TrialRecords]:
    """Fifteen trials of a noisy cell."""
    return simulate_run(SimulatedRun(trials=15, sponge=TRUTH, sensor=NOISY), seed=4)


@pytest.mark.long
def test_twin_writes_a_config_that_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, records: list[TrialRecords],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The fit's twin.toml is an emulated cell: two trials run on it, replay reads it."""
    run_dir = tmp_path / "site-run"
    run_dir.mkdir()
    _serve(monkeypatch, records)
    out = tmp_path / "twin" / "twin.toml"
    assert cli.main(["twin", str(run_dir), "--out", str(out)]) == 0
    document = json.loads((out.parent / "twin.json").read_text())
    assert document["represented"] is True
    assert (out.parent / "twin.md").read_text().startswith("# Twin of the cell")
    assert (out.parent / "twin_heldout.png").stat().st_size > 0
    twin = load_cell_config(out)
    assert twin.robot_emulated and twin.sensor_emulated
    assert twin.emulator.sponge.stiffness_n_per_mm == pytest.approx(2.6, rel=0.05)
    assert sensor_model(twin).noise_std[1] == pytest.approx(0.1, rel=0.15)
    held = document["trials"]["held_out"]
    assert held == [13, 14, 15]
    run_out = tmp_path / "on-twin"
    code = cli.main(["run", "--config", str(out), "--trials", "2", "--out", str(run_out),
                     "--no-progress"])
    assert code == 0
    with open(run_out / "trials.csv") as handle:
        assert len(list(csv.DictReader(handle))) == 2
    capsys.readouterr()
    assert cli.main(["replay", str(run_dir), "--on", str(out), "--model", "forward",
                     "--out", str(tmp_path / "replay")]) == 0
    printed = capsys.readouterr().out
    assert "overall RMS" in printed
    overall = json.loads((tmp_path / "replay" / "replay.json").read_text())["overall_rms_n"]
    assert overall < 0.2


@pytest.mark.long
def test_a_hysteretic_twin_carries_its_hysteresis_and_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A hysteretic foam under a frictional roller: its twin carries h and runs.

    The twin fits h (and mu), reports them with their uncertainty, writes them to
    twin.toml, and two trials run on it.
    """
    truth = SpongeParams(stiffness_n_per_mm=2.6, surface_y_mm=0.5, relaxation_ratio=0.3,
                         surface_slope=0.1, hysteresis_loss=0.2, friction_coefficient=0.3)
    _serve(monkeypatch, simulate_run(SimulatedRun(trials=10, steps=12, burst_samples=10,
                                                  sponge=truth, sensor=NOISY), seed=6))
    run_dir = tmp_path / "site-run"
    run_dir.mkdir()
    out = tmp_path / "twin" / "twin.toml"
    assert cli.main(["twin", str(run_dir), "--out", str(out)]) == 0
    document = json.loads((out.parent / "twin.json").read_text())
    assert document["member"].startswith("hysteretic")
    rows = {row["name"]: row for row in document["parameters"]}
    assert rows["hysteresis_loss"]["determined"] is True
    assert rows["hysteresis_loss"]["sigma"] < 0.01
    assert "hysteresis_loss" in (out.parent / "twin.md").read_text()
    twin = load_cell_config(out)
    assert twin.emulator.sponge.hysteresis_loss == rows["hysteresis_loss"]["value"]
    assert twin.emulator.sponge.hysteresis_loss == pytest.approx(0.2, rel=0.1)
    assert twin.emulator.sponge.hysteresis_depth_mm == rows["hysteresis_depth_mm"]["value"]
    if document["member"] == "hysteretic+friction":
        assert twin.emulator.sponge.friction_coefficient == pytest.approx(
            0.3, abs=3 * rows["friction_coefficient"]["sigma"] + 0.02)
    run_out = tmp_path / "on-twin"
    assert cli.main(["run", "--config", str(out), "--trials", "2", "--out", str(run_out),
                     "--no-progress"]) == 0
    with open(run_out / "trials.csv") as handle:
        assert len(list(csv.DictReader(handle))) == 2


class _RipplingFoam(Sponge):
    """Force that ripples with depth (3 N every 2 mm): no member of any foam family."""

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        depth = self._penetration_mm(position_mm)
        force = 2.0 * depth + 3.0 * math.sin(math.pi * depth) if depth > 0 else 0.0
        return np.array([0.0, force, 0.0])


@pytest.mark.long
def test_a_cell_outside_the_family_gets_no_twin(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Exit 3, "not represented" with the reason, a report but no twin.toml."""
    run = SimulatedRun(trials=10, sensor=NOISY, exploration_mm=2.0)
    _serve(monkeypatch, simulate_run(run, seed=5, sponge=_RipplingFoam(run.sponge)))
    (tmp_path / "run").mkdir()
    out = tmp_path / "twin.toml"
    assert cli.main(["twin", str(tmp_path / "run"), "--out", str(out)]) == 3
    assert "this cell is not represented by the twin" in capsys.readouterr().out
    assert not out.exists()
    assert "not represented" in (tmp_path / "twin.md").read_text()
    document = json.loads((tmp_path / "twin.json").read_text())
    sponge = [row for row in document["parameters"] if row["table"] == "sponge"]
    assert sponge and not any(row["determined"] for row in sponge)


def test_damaged_records_are_a_typed_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The reader's error reaches the user as one line and exit 1."""
    def damaged(run_dir: Path) -> list[TrialRecords]:
        raise RecordsError(f"{run_dir}/records.mcap is damaged")

    monkeypatch.setattr(source, "read_run_records", damaged)
    (tmp_path / "run").mkdir()
    assert cli.main(["twin", str(tmp_path / "run"), "--out", str(tmp_path / "t.toml")]) == 1
    assert "damaged" in capsys.readouterr().err


def test_a_missing_run_directory_is_named(tmp_path: Path) -> None:
    """No such folder: RecordsError naming it."""
    with pytest.raises(RecordsError, match="not a run directory"):
        source.read_run_records(tmp_path / "nowhere")
