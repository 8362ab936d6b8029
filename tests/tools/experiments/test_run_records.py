"""records.mcap: round trip, agreement with trials.csv, crash recovery, damage."""

from __future__ import annotations

import csv
import dataclasses
import logging
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from forcelearn.errors import RecordsFileError, StateFileError
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TareRecord, TrialRecords
from forcelearn.tasks.surface import KGF_N
from forcelearn.tools.cli import main
from forcelearn.tools.experiments.records import (
    PROBE_TRIAL,
    RECORDS_FILE,
    RecordsWriter,
    read_records,
    scan_records,
)

floats = st.floats(allow_nan=True, allow_infinity=False, width=64)
times = st.floats(0.0, 1e6)
xyz = st.tuples(floats, floats, floats)
moves = st.builds(MoveRecord, xyz, xyz, times, times, times)
bursts = st.builds(
    BurstRecord, floats, floats, floats, floats, st.integers(1, 10_000), times, times, floats,
    st.none() | st.tuples(*(floats,) * 6),
)


def trial_of(index: int, draw: Any) -> TrialRecords:
    """A trial of drawn steps and tares, all labelled ``index``."""
    steps = draw(st.lists(st.builds(
        StepRecord, st.just(index), st.integers(0, 40),
        st.sampled_from(["approach", "step", "retreat"]), moves, st.none() | bursts,
    ), max_size=6))
    tares = draw(st.lists(
        st.builds(TareRecord, st.just(index), times, xyz, floats, st.booleans()), max_size=2
    ))
    return TrialRecords(index, steps, tares)


def canonical(trials: list[TrialRecords]) -> list[Any]:
    """Records as nested tuples with NaN spelled out (NaN != NaN would hide equality)."""
    def fix(value: Any) -> Any:
        if isinstance(value, float) and math.isnan(value):
            return "nan"
        if isinstance(value, tuple | list):
            return tuple(fix(v) for v in value)
        return value
    return [fix(dataclasses.astuple(t)) for t in trials]


@given(st.data())
def test_records_round_trip_finished_or_not(tmp_path_factory: pytest.TempPathFactory,
                                            data: st.DataObject) -> None:
    """What is written reads back equal, from a finished file and from one whose writer died."""
    trials = [trial_of(i, data.draw) for i in range(data.draw(st.integers(0, 3)))]
    folder = tmp_path_factory.mktemp("rt")
    writer = RecordsWriter(folder / RECORDS_FILE)
    for trial in trials:
        writer.write_trial(trial)
    died = scan_records(folder / RECORDS_FILE)  # no footer yet: as after a crash
    assert not died.finished and not died.dropped_tail
    assert canonical(died.trials) == canonical(trials)
    writer.close()
    writer.close()  # twice is fine
    assert canonical(read_records(folder)) == canonical(trials)
    assert scan_records(folder / RECORDS_FILE).finished


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An emulated run of 4 trials that probes the sponge first and tares before each trial."""
    folder = tmp_path_factory.mktemp("records")
    config = folder / "cell.toml"
    config.write_text("[task]\ntare_each_trial = true\n")
    out = folder / "run"
    assert main(["run", "--config", str(config), "--trials", "4", "--seed", "3",
                 "--out", str(out), "--no-progress"]) == 0
    return out


def test_the_probes_records_come_first_and_hold_every_reading_of_probe_csv(
    short_run: Path,
) -> None:
    """Trial -1 (asked for) is the probe: its points, and a burst at each probe.csv row's time."""
    probe, *trials = read_records(short_run, probe=True)
    assert probe.trial == PROBE_TRIAL and [t.trial for t in trials] == [0, 1, 2, 3]
    assert canonical(trials) == canonical(read_records(short_run))  # without it by default
    with open(short_run / "probe.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert {s.stage for s in probe.steps} == {"probe"}
    assert {s.index for s in probe.steps} == {int(r["point"]) for r in rows}
    burst_times = {s.burst.start_s for s in probe.steps if s.burst is not None}
    assert {float(r["cell_time_s"]) for r in rows} <= burst_times


def test_a_runs_records_agree_with_its_trials_csv(short_run: Path) -> None:
    """Start force, force RMS, steps and cell time of trials.csv follow from the records."""
    with open(short_run / "trials.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    desired = 2.0 * KGF_N  # the default task's
    trials = read_records(short_run)
    assert [t.trial for t in trials] == [int(r["index"]) for r in rows] == [0, 1, 2, 3]
    for trial, row in zip(trials, rows, strict=True):
        stages = [s.stage for s in trial.steps]
        approach = [s for s in trial.steps if s.stage == "approach"]
        assert approach and stages.index("step") > stages.index("approach")
        start = approach[-1].burst  # the start press's measurement
        assert start is not None and start.filtered_n == float(row["start_force_n"])
        last_of_step: dict[int, BurstRecord] = {}
        for step in trial.steps:
            if step.stage == "step" and step.burst is not None:
                last_of_step[step.index] = step.burst
        forces = [last_of_step[k].filtered_n for k in sorted(last_of_step)]
        assert sorted(last_of_step) == list(range(1, len(forces) + 1))
        steps = int(row["steps"]) + (row["failed"] == "True")
        assert len(forces) == steps
        rms = math.sqrt(sum((f - desired) ** 2 for f in forces) / len(forces))
        assert rms == pytest.approx(float(row["force_rms_n"]), rel=1e-12)
        # the trial's time ends with its last move; the zero check after it may move up first
        ends = [s.move.settled_s - trial.steps[0].move.start_s for s in trial.steps]
        assert any(end == pytest.approx(float(row["cell_time_s"]), abs=1e-9) for end in ends)
        assert ends[-1] >= float(row["cell_time_s"]) - 1e-9
        for step in trial.steps:  # the clock runs forward through each move
            move = step.move
            assert move.start_s <= move.in_position_s <= move.settled_s
            burst = step.burst
            if burst is not None and burst.count == 1:  # a guard sample on the way
                assert burst.first_n == burst.last_n == burst.mean_n and burst.std_n == 0
            elif burst is not None:
                assert burst.std_n > 0 and burst.span_s > 0
        # the tare before its press, then the zero check at its end (the default), in free space;
        # the first press on that new zero, with nothing to compare with, is made twice from a
        # zero checked before each (two more)
        assert len(trial.tares) == 4
        assert {t.trial for t in trial.tares} == {trial.trial}
        assert all(t.accepted and abs(t.reading_n) <= 2.0 for t in trial.tares)
        assert trial.tares[-1].time_s >= trial.steps[-1].move.settled_s


def test_a_truncated_tail_is_recovered_up_to_the_last_whole_trial(
    short_run: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A writer that died mid-trial: every whole trial before it is read, the tail reported."""
    whole = read_records(short_run)
    writer = RecordsWriter(tmp_path / RECORDS_FILE, whole[:2])
    two = (tmp_path / RECORDS_FILE).stat().st_size
    writer.write_trial(whole[2])
    three = (tmp_path / RECORDS_FILE).stat().st_size
    data = (tmp_path / RECORDS_FILE).read_bytes()
    for cut in range(two + 1, three, max(1, (three - two) // 40)):  # inside trial 2's messages
        (tmp_path / RECORDS_FILE).write_bytes(data[:cut])
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            scan = scan_records(tmp_path / RECORDS_FILE)
        assert [t.trial for t in scan.trials] == [0, 1], cut
        assert scan.dropped_tail and "dropped the rest" in caplog.text
        assert canonical(scan.trials) == canonical(whole[:2])


def test_resume_rewinds_the_records_to_the_checkpoint(short_run: Path, tmp_path: Path) -> None:
    """Records written past the checkpoint (killed before it was saved) are dropped on resume."""
    from forcelearn.site.config import load_cell_config
    from forcelearn.tools.experiments.surface_run import records_writer
    from forcelearn.tools.experiments.surface_state import SurfaceRun
    from forcelearn.trainer import TrialRecord

    whole = read_records(short_run)
    writer = RecordsWriter(tmp_path / RECORDS_FILE, whole)  # four trials, no footer
    run = SurfaceRun(load_cell_config(), trials=10, seed=3, out=tmp_path)
    run.result.records = [TrialRecord(i, "generalized", 20, False, 0.1, 0.5, 9.0)
                          for i in range(3)]  # the checkpoint holds three
    resumed = records_writer(run, resumed=True)
    resumed.write_trial(dataclasses.replace(whole[3], trial=3))
    resumed.close()
    writer.close()  # the dead writer's handle: its file was replaced, nothing reaches it
    again = read_records(tmp_path)
    assert [t.trial for t in again] == [0, 1, 2, 3]
    assert canonical(again) == canonical(whole)


def damage(data: bytes, how: str) -> bytes:
    """A finished records file damaged one way."""
    if how == "not mcap":
        return b"PK\x03\x04" + data[4:]
    if how == "bad json":
        at = data.index(b'{"trial":1,')
        return data[:at] + b"[" + data[at + 1:]
    if how == "count mismatch":
        at = data.index(b'{"trial":1,"steps":')
        return data[:at] + b'{"trial":1,"steps":9' + data[at + len(b'{"trial":1,"steps":') + 1:]
    if how == "cut with footer kept":
        middle = len(data) // 2
        return data[:middle] + data[middle + 100:]
    raise AssertionError(how)


@pytest.mark.parametrize("how", ["not mcap", "bad json", "count mismatch",
                                 "cut with footer kept"])
def test_a_damaged_records_file_is_a_typed_error(short_run: Path, tmp_path: Path,
                                                 how: str) -> None:
    """Damage (not a crash's truncated tail) raises RecordsFileError saying what to do."""
    data = (short_run / RECORDS_FILE).read_bytes()
    (tmp_path / RECORDS_FILE).write_bytes(damage(data, how))
    with pytest.raises(RecordsFileError, match="move it away") as caught:
        read_records(tmp_path)
    assert isinstance(caught.value, StateFileError)


def test_a_run_folder_without_records_is_a_typed_error(tmp_path: Path) -> None:
    """read_records on a folder with no records.mcap says so."""
    with pytest.raises(RecordsFileError, match="does not exist"):
        read_records(tmp_path)


def test_the_trial_recorder_pairs_bursts_with_moves_and_numbers_the_trial() -> None:
    """A burst joins the move before it; a second one stands alone at the pose held."""
    from types import SimpleNamespace

    from forcelearn.devices import Pose
    from forcelearn.tools.experiments.run_recorder import TrialRecorder

    cell = SimpleNamespace(stage=("approach", 0), time_s=4.0, known_pose=Pose(1.0, 2.0, 3.0))
    recorder = TrialRecorder(cell)  # type: ignore[arg-type]
    move = MoveRecord((1.0, 2.0, 3.0), (1.0, 2.0, 3.0), 3.0, 3.5, 4.0)
    burst = BurstRecord(5.0, 0.1, 5.1, 4.9, 25, 4.0, 0.024, 5.0)
    recorder.on_move(move)
    recorder.on_burst(burst)
    cell.stage, cell.time_s = ("probe", 2), 6.0
    recorder.on_burst(burst)  # read again after a dwell, no move
    recorder.on_tare(TareRecord(-1, 6.0, (1.0, 2.0, 3.0), 0.2, True))
    trial = recorder.take(7)
    first, again = trial.steps
    assert first == StepRecord(7, 0, "approach", move, burst)
    assert (again.stage, again.index, again.burst) == ("probe", 2, burst)
    assert again.move.commanded_mm == (1.0, 2.0, 3.0)
    assert (again.move.start_s, again.move.in_position_s, again.move.settled_s) == (6.0,) * 3
    assert [t.trial for t in trial.tares] == [7]
    assert recorder.take(8) == TrialRecords(8)  # taken: the next trial starts empty
