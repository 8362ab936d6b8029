"""`forcelearn sim contour` end to end: files, summary fields, config errors."""

import csv
import json
from pathlib import Path

import pytest

from forcelearn.tools.cli import main


def test_sim_contour_writes_the_run_directory(
    tmp_path: Path, required_summary_keys: frozenset[str]
) -> None:
    """Summary, trials table, step logs, learner state and five figures land in --out."""
    out = tmp_path / "run"
    code = main(
        ["sim", "contour", "--trials", "40", "--seed", "3", "--out", str(out), "--no-progress"]
    )
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= required_summary_keys
    assert summary["task"] == "contour" and summary["seed"] == 3 and summary["trials"] == 40
    assert summary["converged_trial"] is None  # 40 trials cannot converge
    with (out / "trials.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 40
    assert set(rows[0]) >= {"index", "phase", "steps", "failed", "mean_r", "force_rms_n"}
    assert (
        sum(int(r["steps"]) for r in rows) + sum(r["failed"] == "True" for r in rows)
        == summary["steps"]
    )
    assert (out / "steps_final.csv").exists() and (out / "learner.npz").exists()
    assert len(list(out.glob("fig*.png"))) == 5


def test_specialized_only_flag_and_config_file(tmp_path: Path) -> None:
    """--specialized-only never leaves the specialized phase; the config sets the budget."""
    config = tmp_path / "c.toml"
    config.write_text("[run]\ntrials = 12\n[learner]\ngamma = 0.8\n")
    out = tmp_path / "run"
    assert (
        main(
            [
                "sim",
                "contour",
                "--config",
                str(config),
                "--specialized-only",
                "--out",
                str(out),
                "--no-progress",
                "--no-figures",
            ]
        )
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"] == 12 and summary["mode"] == "specialized-only"
    with (out / "trials.csv").open() as handle:
        assert {r["phase"] for r in csv.DictReader(handle)} == {"specialized"}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[learner]\ngama = 0.8\n", "learner.gama"),
        ("[robot]\n", "unknown section"),
        ("[learner]\ngamma = 2.0\n", "gamma"),
        ("not toml ][", "not valid TOML"),
    ],
)
def test_config_errors_name_the_key(
    tmp_path: Path, text: str, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bad config exits 1 with a message naming the key, before any run."""
    config = tmp_path / "c.toml"
    config.write_text(text)
    assert main(["sim", "contour", "--config", str(config), "--out", str(tmp_path / "o")]) == 1
    assert message in capsys.readouterr().err


def test_example_configs_load() -> None:
    """Every shipped contour example is a valid config."""
    from forcelearn.tools.experiments.contour import load_config

    root = Path(__file__).resolve().parents[3] / "examples"
    config = load_config(root / "contour-plain.toml")
    assert config.learner.sigma_min == 0.05 and config.trials == 4000
    assert config.learner.extent == (5, 5)
