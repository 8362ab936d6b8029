"""`forcelearn run` end to end on the emulated cell: outputs, Ctrl-C, SIGKILL and resume."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from forcelearn.errors import StateFileError
from forcelearn.learning import load_learner
from forcelearn.records import StepRecord, TrialRecords
from forcelearn.tools.cli import main
from forcelearn.tools.experiments.records import read_records

TRIALS = 10
"""Trials of the uninterrupted run; the SIGKILL test stops at half of them."""
TIMING_KEYS = {"wall_s", "steps_per_s", "realtime_factor"}


def run_cli(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """Run the forcelearn CLI in a child process."""
    code = "import sys; from forcelearn.tools.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def trials_done(out: Path) -> int:
    """Trials in the checkpoint of a run directory (0 when there is none yet)."""
    path = out / "checkpoint.npz"
    if not path.exists():
        return 0
    try:
        return int(load_learner(path)[1]["trials_done"])
    except StateFileError:  # pragma: no cover - the file is replaced atomically
        return 0


@pytest.fixture
def uninterrupted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete run of TRIALS trials with seed 5."""
    out = tmp_path_factory.mktemp("whole") / "run"
    done = run_cli(
        "run", "--trials", str(TRIALS), "--seed", "5", "--out", str(out), "--no-progress"
    )
    assert done.returncode == 0, done.stderr
    return out


def check_run_outputs(uninterrupted: Path, required_summary_keys: frozenset[str]) -> None:
    """The run directory holds every promised output."""
    summary = json.loads((uninterrupted / "summary.json").read_text())
    assert set(summary) >= required_summary_keys
    assert summary["task"] == "surface" and summary["trials"] == TRIALS
    lines = (uninterrupted / "trials.csv").read_text().splitlines()
    assert len(lines) == TRIALS + 1
    for name in (
        "steps_first.csv",
        "steps_mid.csv",
        "steps_final.csv",
        "checkpoint.npz",
        "fig12_positions.png",
        "fig13_contact_force.png",
        "fig14_initial_force.png",
    ):
        assert (uninterrupted / name).exists(), name


# The child runs the real CLI with one hook: after the checkpoint of trial ``stop_at`` it
# prints "checkpoint <n>" and blocks on stdin, so the parent signals it at a known point
# instead of polling the checkpoint file against the clock.
PAUSING_CLI = """
import signal
import sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # even under a background job
import forcelearn.tools.commands.run as rc
stop_at = int(sys.argv[1])
original = rc.execute
def execute(run, checkpoint, on_trial=None, **hooks):
    def hook(record, learner):
        if on_trial is not None:
            on_trial(record, learner)
        if len(run.result.records) == stop_at:
            print("checkpoint", stop_at, flush=True)
            sys.stdin.readline()  # wait here for the parent's signal
    return original(run, checkpoint, on_trial=hook, **hooks)
rc.execute = execute
from forcelearn.tools.cli import main
sys.exit(main(sys.argv[2:]))
"""


def start_paused_at(stop_at: int, *args: str) -> subprocess.Popen[str]:
    """Start ``forcelearn *args``; return once trial ``stop_at`` is checkpointed and paused."""
    child = subprocess.Popen(
        [sys.executable, "-c", PAUSING_CLI, str(stop_at), *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None
    line = child.stdout.readline()  # the event; pytest-timeout bounds a hang
    if line.strip() != f"checkpoint {stop_at}":
        child.kill()
        _, err = child.communicate(timeout=10)
        raise AssertionError(f"the run did not reach trial {stop_at}: {line!r} {err}")
    return child


def comparable(trials: list[TrialRecords]) -> str:
    """Records as text, but for the filter's output on the guard samples of an approach.

    The filter's track is not in the checkpoint: a resumed run's first approach reads
    its guard samples through a fresh filter (the task resets it before the start
    measurement, so the learner never sees the difference).
    """
    def unfiltered(step: StepRecord) -> StepRecord:
        if step.stage != "approach" or step.burst is None or step.burst.count != 1:
            return step
        return dataclasses.replace(step, burst=dataclasses.replace(step.burst, filtered_n=0.0))
    return repr([(t.trial, [unfiltered(step) for step in t.steps], t.tares) for t in trials])


@pytest.mark.long
def test_sigkill_mid_run_then_resume_ends_bit_identical(
    uninterrupted: Path, tmp_path: Path, required_summary_keys: frozenset[str]
) -> None:
    """A run writes every output; one killed with SIGKILL and resumed equals it bit for bit.

    (One test for both, so the uninterrupted run is made once whatever the workers.)
    """
    check_run_outputs(uninterrupted, required_summary_keys)
    out = tmp_path / "run"
    child = start_paused_at(
        TRIALS // 2,
        "run", "--trials", str(TRIALS), "--seed", "5", "--out", str(out), "--no-progress",
    )
    try:
        os.kill(child.pid, signal.SIGKILL)
        child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
        child.communicate(timeout=10)
    assert child.returncode == -signal.SIGKILL
    assert trials_done(out) == TRIALS // 2
    resumed = run_cli("run", "--resume", str(out), "--no-progress")
    assert resumed.returncode == 0, resumed.stderr
    assert (out / "trials.csv").read_text() == (uninterrupted / "trials.csv").read_text()
    for name in ("steps_final.csv", "steps_mid.csv", "steps_first.csv"):
        assert (out / name).read_text() == (uninterrupted / name).read_text(), name
    whole, whole_meta = load_learner(uninterrupted / "checkpoint.npz")
    again, again_meta = load_learner(out / "checkpoint.npz")
    assert np.array_equal(whole.weights, again.weights)
    assert np.array_equal(whole.predictions, again.predictions)
    assert whole.rng.bit_generator.state == again.rng.bit_generator.state
    assert whole_meta["emulator"] == again_meta["emulator"]
    # the killed writer left no footer; the resume kept its whole trials and went on:
    # the same records, none twice, none lost
    assert [t.trial for t in read_records(out)] == list(range(TRIALS))
    assert comparable(read_records(out, probe=True)) == comparable(
        read_records(uninterrupted, probe=True)
    )
    assert read_records(out, probe=True)[0].trial == -1  # the probe's, kept across the resume
    a = json.loads((uninterrupted / "summary.json").read_text())
    b = json.loads((out / "summary.json").read_text())
    assert {k: v for k, v in a.items() if k not in TIMING_KEYS} == {
        k: v for k, v in b.items() if k not in TIMING_KEYS
    }


def test_ctrl_c_stops_and_leaves_a_resumable_checkpoint(
    tmp_path: Path, configured_map_toml: str
) -> None:
    """SIGINT mid-run: exit 130, the robot stopped, the checkpoint whole and resumable."""
    out = tmp_path / "run"
    config = tmp_path / "cell.toml"
    config.write_text(configured_map_toml)  # no probe: Ctrl-C is the point
    child = start_paused_at(3, "run", "--config", str(config), "--trials", "200",
                            "--out", str(out), "--no-progress")
    try:
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=120)  # bounded; a loaded host is slow, not wrong
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(timeout=10)
    assert child.returncode == 130, err
    assert "--resume" in err
    done = trials_done(out)
    assert done == 3
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"] == done  # outputs written for the whole trials, nothing partial
    resumed = run_cli("run", "--resume", str(out), "--trials", str(done + 2), "--no-progress")
    assert resumed.returncode == 0, resumed.stderr
    assert json.loads((out / "summary.json").read_text())["trials"] == done + 2
    assert [t.trial for t in read_records(out)] == list(range(done + 2))


def test_resume_and_new_run_refuse_the_wrong_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--resume on an empty folder, or a new run over an old one, fail with what to do."""
    assert main(["run", "--resume", str(tmp_path), "--no-progress"]) == 1
    assert "nothing to resume" in capsys.readouterr().err
    (tmp_path / "checkpoint.npz").write_bytes(b"x")
    assert main(["run", "--out", str(tmp_path), "--no-progress"]) == 1
    assert "already holds a run" in capsys.readouterr().err


def test_a_sensor_failing_mid_run_stops_the_robot_and_keeps_whole_trials(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, configured_map_toml: str
) -> None:
    """The JR3 goes silent for good after trial 3: the robot stops, 3 trials are kept.

    The run retracts and tries to restart the sensor; a sensor that
    never answers ends it with RecoveryFailed, the tool retracted in free space.
    """
    from forcelearn.emulators.jr3.faults import Jr3FaultConfig
    from forcelearn.tasks.recovery import RecoveryFailed
    from forcelearn.tools.experiments import surface_run
    from forcelearn.tools.experiments.fault_recovery import read_events
    from forcelearn.tools.experiments.surface_state import prepare_run

    sessions = []
    stops: list[bool] = []
    stops_before_close: list[int] = []

    class RecordingSession(surface_run.CellSession):
        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            sessions.append(self)
            robot = self.robot
            original_stop = robot.stop

            def counted_stop() -> None:
                stops.append(True)
                original_stop()

            robot.stop = counted_stop  # type: ignore[method-assign]

        def close(self) -> None:
            stops_before_close.append(len(stops))
            super().close()

    monkeypatch.setattr(surface_run, "CellSession", RecordingSession)

    def silence_after_three(record: object, learner: object) -> None:
        if record.index == 2:  # type: ignore[attr-defined]
            sessions[0].sensor_emulator.set_faults(Jr3FaultConfig(silent=True))

    out = tmp_path / "run"
    config = tmp_path / "cell.toml"
    config.write_text(configured_map_toml)  # no probe: the failing sensor is the point
    run, checkpoint = prepare_run(config, out, 10, 3, resume=False)
    with pytest.raises(RecoveryFailed, match="did not come back") as failed:
        surface_run.execute(run, checkpoint, on_trial=silence_after_three)
    assert not failed.value.in_contact
    assert read_events(out)[-1]["action"] == "ended"
    assert stops_before_close[0] >= 1, "the run did not stop the robot before closing"
    assert trials_done(out) == 3
    assert json.loads((out / "summary.json").read_text())["trials"] == 3


def test_an_ended_but_unsaved_trial_is_rolled_back_before_outputs() -> None:
    """Interrupted between a trial's end and its checkpoint: outputs match the checkpoint."""
    from forcelearn.site.config import load_cell_config
    from forcelearn.tasks.surface import TrialTrace
    from forcelearn.tools.experiments.surface_state import SurfaceRun
    from forcelearn.trainer import TrialLog, TrialRecord

    run = SurfaceRun(load_cell_config(), trials=10, seed=0, out=Path("."))
    for i in range(3):
        run.result.records.append(TrialRecord(i, "generalized", 20, False, 0.1, 0.5, 9.0))
        run.traces.append(
            TrialTrace(mean_y_mm=[1.0], command_y_mm=[1.1], shift_mm=0.0, force_n=[9.0])
        )
        run.result.steps += 20
        run.result.last_log = TrialLog(i, "generalized")
        run.map_shift_mm, run.tares = -0.1 * i, (i + 1, 0)
        if i < 2:
            run.mark_saved()
    run.result.switch_trial, run.result.switch_log = 2, run.result.last_log
    run.rollback_to_saved()
    assert len(run.result.records) == len(run.traces) == 2
    assert run.result.steps == 40 and run.result.last_log.index == 1
    assert run.map_shift_mm == -0.1 and run.tares == (2, 0)  # the unsaved trial's are gone
    assert run.result.switch_trial is None and run.result.switch_log is None


def test_the_checkpoint_keeps_each_trials_wear_shift(tmp_path: Path) -> None:
    """Each trial's map shift survives the checkpoint; an older checkpoint without it reads 0.

    The stuck monitor replays the traces on resume, so a lost shift would move
    the range's edges of every trial before the resume.
    """
    import numpy as np

    from forcelearn.errors import StateFileError
    from forcelearn.site.config import load_cell_config
    from forcelearn.tasks.surface import TrialTrace
    from forcelearn.tools.experiments.surface_state import (
        SurfaceRun,
        history_arrays,
        history_from_arrays,
    )
    from forcelearn.trainer import TrialRecord

    run = SurfaceRun(load_cell_config(), trials=10, seed=0, out=tmp_path)
    for i, shift in enumerate((0.0, -0.25, -0.5)):
        run.result.records.append(TrialRecord(i, "generalized", 2, False, 0.1, 0.5, 9.0))
        run.traces.append(TrialTrace(mean_y_mm=[1.0, 2.0], command_y_mm=[1.1, 2.1],
                                     shift_mm=shift, force_n=[9.0, 9.5]))
    arrays = history_arrays(run)
    again = SurfaceRun(load_cell_config(), trials=10, seed=0, out=tmp_path)
    history_from_arrays(again, arrays)
    assert again.traces == run.traces
    old = {k: v for k, v in arrays.items() if k not in ("trace_shift_mm", "trace_force_n")}
    history_from_arrays(again, old)
    assert [t["shift_mm"] for t in again.traces] == [0.0, 0.0, 0.0]
    assert all(np.isnan(t["force_n"]).all() for t in again.traces)  # not kept before: NaN
    damaged = {**arrays, "trace_shift_mm": np.zeros(2)}
    with pytest.raises(StateFileError, match="trial shifts"):
        history_from_arrays(again, damaged)
