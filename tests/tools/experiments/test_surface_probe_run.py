"""The probe inside ``forcelearn run``: map from the fit, kept on resume, stuck runs said so."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from forcelearn.tasks.surface_diagnosis import StuckMonitor
from forcelearn.tools.cli import main
from forcelearn.tools.experiments import surface_run


def test_a_resumed_run_does_not_probe_again_and_keeps_the_map(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The probe runs once; the resumed run reads its result and map from the checkpoint."""
    out = tmp_path / "run"
    assert main(["run", "--out", str(out), "--trials", "2", "--no-progress"]) == 0
    first = json.loads((out / "summary.json").read_text())
    assert first["output_map"]["source"] == "probe"
    assert len(first["probe_fits"]) == 7  # the warm start's path: 3 points and 4 refine points
    assert (out / "probe.csv").exists() and (out / "probe.png").exists()

    def no_probe(*args: object, **kwargs: object) -> None:
        raise AssertionError("the probe ran again on resume")

    monkeypatch.setattr(surface_run.SurfaceProbe, "run", no_probe)
    assert main(["run", "--resume", str(out), "--trials", "3", "--no-progress"]) == 0
    second = json.loads((out / "summary.json").read_text())
    assert second["trials"] == 3
    assert second["output_map"] == first["output_map"]
    assert second["probe_fits"] == first["probe_fits"]


def test_a_range_that_cannot_reach_the_force_warns_and_fails_require_converged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A configured map too shallow for the force: warned, diagnosed, exit 3.

    The commands sit at the deep end or no trial completes: one warning per
    sign, converged false with a diagnosis naming the key, exit 3 under
    --require-converged.
    """

    @dataclasses.dataclass
    class QuickMonitor(StuckMonitor):
        edge_trials: int = 5
        stall_trials: int = 8

    monkeypatch.setattr(surface_run, "StuckMonitor", QuickMonitor)
    config = tmp_path / "cell.toml"
    config.write_text(
        "[task]\noutput_centre_y_mm = -2.0\noutput_scale_mm = 5.0\nmax_offset_mm = 1.0\n"
    )
    out = tmp_path / "run"
    argv = ["run", "--config", str(config), "--out", str(out), "--trials", "12", "--no-progress"]
    assert main([*argv, "--require-converged"]) == 3
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if "WARNING learning is stuck" in line]
    assert 1 <= len(warnings) <= 2
    assert len(set(warnings)) == len(warnings)  # each sign once
    assert all("task.max_offset_mm" in w for w in warnings)
    assert "NOT CONVERGED" in err.strip().splitlines()[-1]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] is False
    assert "task.max_offset_mm" in summary["diagnosis"]
    assert summary["output_map"]["source"] == "config"
    assert not (out / "probe.csv").exists()  # the whole map was configured: no probe


@pytest.mark.parametrize(
    ("stiffness", "force"),
    [
        pytest.param(4.0, 4.903325, id="stiff-sponge-half-kgf", marks=pytest.mark.convergence),
        pytest.param(1.0, 4.903325, id="soft-sponge-half-kgf"),
        pytest.param(4.0, 29.41995, id="stiff-sponge-3kgf", marks=pytest.mark.convergence),
        pytest.param(1.2, 19.6133, id="issue-soft-sponge-2kgf", marks=pytest.mark.convergence),
    ],
)
def test_a_changed_sponge_or_force_converges_without_retuning(
    stiffness: float, force: float, tmp_path: Path
) -> None:
    """A changed sponge and force converge with the probe's map (stopped once converged).

    Only the sponge or the force changes; every other key is the default. The
    soft sponge at 0.5 kgf follows the surface and converges at trial 12 (seed
    0, ~13 s), so it runs in the default suite; the others take 24-80 trials
    (``-m convergence``; the stiff 0.5 kgf corner's start presses and resume
    are in test_surface_follow_run.py). The full grid (0.5x-2x stiffness x
    0.5-3 kgf x 3 seeds) is the study in docs/results/surface.md.
    """
    config = tmp_path / "cell.toml"
    config.write_text(
        f"[task]\ndesired_force_n = {force}\n[emulator.sponge]\nstiffness_n_per_mm = {stiffness}\n"
        "[run]\nstop_after_converged = 1\n"
    )
    out = tmp_path / "run"
    argv = ["run", "--config", str(config), "--out", str(out), "--no-progress"]
    assert main([*argv, "--require-converged"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] is True and summary["diagnosis"] is None
    assert summary["converged_trial"] < 300
