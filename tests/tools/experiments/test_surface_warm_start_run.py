"""``forcelearn run`` with the warm start, wear following, feasibility and the end verdict.

Short runs of the emulated cell (1-12 trials); the 10-seed figures are the
study in docs/results/surface.md.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from forcelearn.learning import SRVLearner
from forcelearn.tasks.surface_probe import ContactFit, ProbeResult
from forcelearn.tasks.surface_warm_start import aimed_force_n
from forcelearn.tools.cli import main

DATA = Path(__file__).parent / "data"
SOFT_WEARING_FAST = (
    "[task]\ndesired_force_n = 21.0\n"
    "[emulator.sponge]\nstiffness_n_per_mm = 0.8\nrelaxation_ratio = 0.8\n"
    "softening_passes = 4.0\n"
)
"""A 0.8 N/mm foam that loses 30 % of its stiffness within a few passes: 21 N is in reach
fresh (26 mm of 38) and out of it worn on its softer patch (the issue's cell, sped up)."""


def _run(tmp_path: Path, name: str, config: str | None, *args: str) -> tuple[int, Path]:
    out = tmp_path / name
    argv = ["run", "--out", str(out), "--no-progress", *args]
    if config is not None:
        path = tmp_path / f"{name}.toml"
        path.write_text(config)
        argv += ["--config", str(path)]
    return main(argv), out


def _summary(out: Path) -> dict:  # type: ignore[type-arg]
    return json.loads((out / "summary.json").read_text())  # type: ignore[no-any-return]


def _first_mean_commands(out: Path) -> np.ndarray:
    """The Y of μ at every step of the first trial (mm), through the run's constant map."""
    choice = _summary(out)["output_map"]
    assert choice["path_y_mm"] == []  # the default cell keeps a constant centre
    rows = list(csv.DictReader((out / "steps_first.csv").open()))
    means = np.array([float(r["mean_0"]) for r in rows])
    offsets = np.clip(means * choice["scale_mm"], -choice["max_offset_mm"],
                      choice["max_offset_mm"])
    return np.asarray(choice["centre_y_mm"] + offsets)


@pytest.fixture
def frozen(monkeypatch: pytest.MonkeyPatch) -> None:
    """The learner acts but learns nothing: trial 0's means are those it started with.

    (Learning within trial 0 moves the means of boxes not yet reached, by eq. (3).)
    """
    monkeypatch.setattr(SRVLearner, "learn", lambda self, step, r: None)


@pytest.mark.usefixtures("frozen")
def test_the_warm_learners_first_trial_is_the_probes_path(tmp_path: Path) -> None:
    """By default the SRV means of trial 0 command where the probe's fits give the force.

    The force the sensor will read: the fits' force plus its free-space reading at
    the probe's end (its bias drift, which the task's readings carry).
    """
    from forcelearn.site.config import load_cell_config

    code, out = _run(tmp_path, "warm", None, "--trials", "1")
    assert code == 0
    summary = _summary(out)
    assert summary["learner_start"] == "probe"
    fits = summary["probe_fits"]
    assert len(fits) == 7  # the 3 points and the 4 refine points: the path has the waves
    baselines = json.loads((out / "probe.json").read_text())["baselines_n"]
    probe = ProbeResult(fits=[ContactFit(**f) for f in fits], baselines_n=baselines)
    task = load_cell_config().task
    path = probe.target_path_mm(task, aimed_force_n(probe, task))
    assert _first_mean_commands(out) == pytest.approx(list(path), abs=1e-6)


@pytest.mark.usefixtures("frozen")
def test_the_cold_start_is_one_key_away(tmp_path: Path) -> None:
    """[run] learner_start = "cold": μ = 0 at every step, the paper's 3-point probe."""
    code, out = _run(tmp_path, "cold", '[run]\nlearner_start = "cold"\n', "--trials", "1")
    assert code == 0
    summary = _summary(out)
    assert summary["learner_start"] == "cold"
    assert len(summary["probe_fits"]) == 3
    rows = list(csv.DictReader((out / "steps_first.csv").open()))
    assert [float(r["mean_0"]) for r in rows] == [0.0] * 20


def test_an_unknown_start_is_refused_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A typo is refused before any device opens."""
    code, _ = _run(tmp_path, "typo", '[run]\nlearner_start = "warm"\n', "--trials", "1")
    assert code != 0
    assert "run.learner_start" in capsys.readouterr().err


def test_a_constant_centre_map_follows_the_sponges_set(tmp_path: Path) -> None:
    """A sponge that sets 6 mm within a few passes: the constant map and start press move down.

    (Cold, so the probe's 3 passes leave most of the set to the trials.)
    """
    fast_set = (
        '[run]\nlearner_start = "cold"\n[emulator.sponge]\nset_mm = 6.0\nset_passes = 6.0\n'
    )
    code, out = _run(tmp_path, "set", fast_set, "--trials", "6")
    assert code == 0
    summary = _summary(out)
    choice = summary["output_map"]
    assert choice["path_y_mm"] == []  # a constant centre, not a followed surface
    assert choice["wear_stiffness_n_per_mm"] == pytest.approx(summary["probe_stiffness_n_per_mm"])
    assert summary["map_shift_mm"] < -0.5  # the 2 mm of set, followed half a step a trial
    low, _ = choice["shift_range_mm"]
    assert summary["map_shift_mm"] >= low
    starts = [float(r["start_force_n"]) for r in csv.DictReader((out / "trials.csv").open())]
    assert starts[-1] > starts[1] - 1.0  # the start press went down with the surface


def test_a_force_the_probe_finds_out_of_reach_is_refused_naming_the_keys(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """3 kgf on a 0.5 N/mm foam needs ~60 mm of 38: refused, with both figures and the keys."""
    config = "[task]\ndesired_force_n = 29.41995\n[emulator.sponge]\nstiffness_n_per_mm = 0.5\n"
    code, out = _run(tmp_path, "deep", config, "--trials", "1")
    assert code != 0
    err = capsys.readouterr().err
    for text in ("task.desired_force_n = 29.42 N", "probe.max_depth_mm = 38", "mm allowed"):
        assert text in err, text
    assert not (out / "checkpoint.npz").exists()


def test_a_foam_that_wears_out_of_reach_is_diagnosed_and_fails_require_converged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The run's own estimate names the foam, with the figures; exit 3; summary and journal."""
    code, out = _run(tmp_path, "worn", SOFT_WEARING_FAST, "--trials", "12", "--require-converged")
    assert code == 3
    err = capsys.readouterr().err
    assert "WARNING the desired force is out of the foam's reach" in err
    summary = _summary(out)
    feasibility = summary["feasibility"]
    assert feasibility["out_of_reach_at_end"] is True
    latest = feasibility["latest"]
    assert latest["reason"] == "foam"
    assert latest["needed_depth_mm"] > latest["allowed_depth_mm"]
    assert latest["worn_stiffness_n_per_mm"] < summary["probe_stiffness_n_per_mm"]
    assert latest["force_at_bottom_n"] < summary["desired_force_n"]
    assert summary["in_band_at_end"] is False
    assert "out of the foam's reach" in summary["diagnosis"]
    journal = (out / "live.ndjson").read_text()
    assert "out of the foam's reach" in journal  # the live view's events


def test_the_summary_says_whether_the_run_ended_in_band(tmp_path: Path) -> None:
    """The new fields are there: a 2-trial run has not converged nor ended in band."""
    code, out = _run(tmp_path, "short", '[run]\nlearner_start = "cold"\n', "--trials", "2")
    assert code == 0
    summary = _summary(out)
    assert summary["converged"] is False and summary["in_band_at_end"] is False
    assert summary["trials_out_of_band_after_convergence"] is None
    assert summary["diagnosis"]


def test_a_checkpoint_of_the_previous_version_resumes_as_it_ran(tmp_path: Path) -> None:
    """A version-4 checkpoint (before the warm start, 2 trials, seed 0) resumes cold and untracked.

    Its 2 checkpointed trials are kept as main's own 4-trial run made them; trials 2-3 run on
    today's cell (the emulated JR3 now answers one SYNC a millisecond, as the firmware, so their
    figures are not the old code's), complete, and the same on every resume of that file.
    """
    outs = []
    for name in ("old", "again"):
        out = tmp_path / name
        out.mkdir()
        shutil.copyfile(DATA / "checkpoint_v4" / "checkpoint.npz", out / "checkpoint.npz")
        assert main(["run", "--resume", str(out), "--trials", "4", "--no-progress"]) == 0
        outs.append(out)
    summary = _summary(outs[0])
    assert summary["learner_start"] == "cold"
    assert summary["output_map"]["wear_stiffness_n_per_mm"] is None  # as it ran: no tracking
    assert summary["map_shift_mm"] == 0.0
    rows = (outs[0] / "trials.csv").read_text().splitlines()
    expected = (DATA / "checkpoint_v4" / "trials_main_4.csv").read_text().splitlines()
    assert rows[:3] == expected[:3]  # the header and the two trials the checkpoint holds
    assert len(rows) == 5
    for row in rows[3:]:  # resumed: complete and not failed
        fields = row.split(",")
        assert fields[2] == "20" and fields[3] == "False"
    assert (outs[1] / "trials.csv").read_text() == (outs[0] / "trials.csv").read_text()
