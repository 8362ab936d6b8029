"""Bad input is refused at load, before any device opens: exit 1, one line naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from forcelearn.site import session as cell_session
from forcelearn.tools.cli import main
from forcelearn.tools.commands import probe as probe_command
from forcelearn.tools.experiments import surface_run

CASES = [
    ("[task]\ndesired_force_n = 80.0\n", "task.desired_force_n"),
    ("[task]\ndesired_force_n = 60.0\n", "task.desired_force_n"),
    ("[run]\ntrials = -5\n", "run.trials"),
    ("[run]\ntrials = 0\n", "run.trials"),
    ("[task]\nstart_mm = [900.0, nan, 0.0]\n", "task.start_mm[1]"),
    ("[task]\ndesired_force_n = \"20\"\n", "task.desired_force_n"),
    ("[task]\nsteps_per_trial = 0\n", "task.steps_per_trial"),
    ("[task]\ninput_parts = -1\n", "task.input_parts"),
    ("[task]\nstart_mm = [900.0, -4.0, 800.0]\n", "task.start_mm"),
    ("[task]\nsteps_per_trial = 40\n", "task.z_step_mm"),
    ("[task]\nmax_offset_mm = 80.0\n", "task.max_offset_mm"),
    ("[task]\nretract_y_mm = 70.0\n", "task.retract_y_mm"),
    ("[task]\ntolerance_n = inf\n", "task.tolerance_n"),
    ("[emulator.sponge]\nstiffness_n_per_mm = nan\n", "emulator.sponge.stiffness_n_per_mm"),
    ("[learner]\ngamma = \"high\"\n", "learner.gamma"),
    ("[safety]\nmax_force_n = nan\n", "safety.max_force_n"),
    ("[probe]\nsamples = 0\n", "probe.samples"),
    ("[probe]\nmax_force_ratio = 1.5\n", "probe.max_force_ratio"),
]


@pytest.fixture
def no_devices(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """Any attempt to open the cell is recorded (and fails the command loudly)."""
    opened: list[object] = []

    class Refused:
        def __init__(self, *args: object, **kwargs: object) -> None:
            opened.append(args)
            raise AssertionError("a device was opened")

    # probe_command is imported at the top: imported here, after cell_session was patched,
    # it would bind Refused as its own CellSession for good (monkeypatch would "restore" it).
    monkeypatch.setattr(surface_run, "CellSession", Refused)
    monkeypatch.setattr(cell_session, "CellSession", Refused)
    monkeypatch.setattr(probe_command, "CellSession", Refused)
    return opened


@pytest.mark.parametrize("command", ["run", "probe"])
@pytest.mark.parametrize(
    ("toml", "key"), CASES, ids=[f"{c[1]}-{i}" for i, c in enumerate(CASES)]
)
def test_bad_input_exits_1_with_one_line_naming_the_key(
    toml: str,
    key: str,
    command: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    no_devices: list[object],
) -> None:
    """Bad input exits 1 with one line naming the key."""
    config = tmp_path / "cell.toml"
    config.write_text(toml)
    out = tmp_path / "out"
    argv = [command, "--config", str(config), "--out", str(out)]
    if command == "run":
        argv.append("--no-progress")
    assert main(argv) == 1
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert key in lines[0]
    assert "Traceback" not in err
    assert no_devices == []
    assert not (out / "checkpoint.npz").exists()


def test_a_force_the_sponge_cannot_give_is_refused_after_the_probe(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """50 N on a sponge of 0.5 N/mm needs ~100 mm: refused with the figures, no trial run."""
    config = tmp_path / "cell.toml"
    config.write_text(
        "[task]\ndesired_force_n = 50.0\n[emulator.sponge]\nstiffness_n_per_mm = 0.5\n"
        "[probe]\npoints = [0.5]\n"
    )
    out = tmp_path / "run"
    assert main(["run", "--config", str(config), "--out", str(out), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "task.desired_force_n = 50 N needs" in err[0] and "mm allowed" in err[0]
    assert (out / "probe.csv").exists() and not (out / "checkpoint.npz").exists()
