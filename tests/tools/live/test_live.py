"""The live page: model, journal, read-only server, and `forcelearn run --live` end to end."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from forcelearn.tools.live.journal import (
    JOURNAL,
    JournalFollower,
    JournalWriter,
    load_run_directory,
    replay_until_trial,
)
from forcelearn.tools.live.model import TRIAL_FIELDS, LiveMeta, LiveModel
from forcelearn.tools.live.publish import LivePublisher
from forcelearn.tools.live.server import LiveServer, bind_warning
from forcelearn.trainer import TrialRecord, converged_trial

META = LiveMeta(task="surface", desired_force_n=19.6133, steps_per_trial=3, trials_target=50)
CLI = "import sys; from forcelearn.tools.cli import main; sys.exit(main(sys.argv[1:]))"


def record(index: int, rms: float, failed: bool = False, steps: int = 3) -> TrialRecord:
    """A trial record with the figures that matter here."""
    return TrialRecord(index, "generalized", steps, failed, 0.1, rms, 12.0, 1.5)


def feed(model: LiveModel, index: int, forces: list[float], rms: float, failed: bool = False):
    """One trial of len(forces) steps into the model."""
    for k, force in enumerate(forces):
        model.step(index, "generalized", {"step": float(k + 1), "force_n": force}, 1.0)
    model.trial(record(index, rms, failed, len(forces)), False, 1.0)


def test_model_keeps_present_previous_best_first_and_the_curve() -> None:
    """Traces follow the trials; best is the lowest RMS among complete trials."""
    model = LiveModel(META)
    feed(model, 0, [10.0, 11.0, 12.0], 8.0)
    feed(model, 1, [18.0, 19.0, 20.0], 0.7)
    feed(model, 2, [30.0], 10.0, failed=True)
    model.step(3, "generalized", {"step": 1.0, "force_n": 19.0}, 2.0)
    state = model.snapshot()
    assert state["trials"]["index"] == [0, 1, 2]
    assert state["trials"]["failed"] == [False, False, True]
    assert state["first"]["trial"] == 0 and state["best"]["trial"] == 1
    assert state["previous"]["trial"] == 2 and state["present"]["trial"] == 3
    assert [r["force_n"] for r in state["present"]["rows"]] == [19.0]
    assert state["marks"]["failures"] == 1
    assert state["status"]["steps"] == 8
    assert model.snapshot(since=2)["trials"]["index"] == [2]


def test_model_convergence_matches_the_trainer_rule() -> None:
    """The incremental convergence mark equals trainer.converged_trial on the same records."""
    rng = np.random.default_rng(1)
    model, records = LiveModel(META), []
    for i in range(200):
        rec = record(i, float(rng.choice([0.5, 2.0], p=[0.9, 0.1])), bool(rng.random() < 0.05))
        records.append(rec)
        model.trial(rec, False, 0.0)
    expected = converged_trial(records, META.steps_per_trial, META.desired_force_n)
    assert expected is not None
    assert model.snapshot()["marks"]["converged_trial"] == expected


def test_a_redone_trial_replaces_the_later_ones() -> None:
    """A resumed run redoing trial 1 drops trials 1.. and changes the epoch."""
    model = LiveModel(META)
    for i in range(3):
        feed(model, i, [19.0, 19.0, 19.0], 0.5)
    feed(model, 1, [15.0, 15.0, 15.0], 4.0)
    state = model.snapshot()
    assert state["trials"]["index"] == [0, 1] and state["trials"]["force_rms_n"][1] == 4.0
    assert state["epoch"] == 1


def shown(model: LiveModel) -> dict[str, Any]:
    """What the page shows of a model: its snapshot without the update counter."""
    return {key: value for key, value in model.snapshot().items() if key != "version"}


def test_journal_replayed_to_a_trial_is_the_live_page_during_that_trial(tmp_path: Path) -> None:
    """The screenshot program's replay equals the live model as trial k's last step was drawn."""
    learner = SimpleNamespace(phase=SimpleNamespace(name="SPECIALIZED"))
    live = LiveModel(META)
    journal = JournalWriter(tmp_path / JOURNAL)
    publisher = LivePublisher(META, live, journal)
    rng = np.random.default_rng(3)
    during: dict[int, dict[str, Any]] = {}
    for index in range(6):
        for step in range(1, 4):
            limit = float(index == 2 and step == 2)
            row = {"step": float(step), "force_n": float(rng.normal(19, 2)), "limit_hit": limit}
            publisher.on_step(index, "generalized", row)
        during[index] = shown(live)
        rec = record(index, float(rng.uniform(0.2, 3.0)), failed=index == 2)
        publisher.on_trial(rec, learner)  # type: ignore[arg-type]
    publisher.finish()
    for index in (0, 2, 5):
        replayed = LiveModel(META)
        replay_until_trial(tmp_path / JOURNAL, replayed, index)
        assert shown(replayed) == during[index]
        assert during[index]["status"]["trials_done"] == index
        assert during[index]["present"]["trial"] == index
    with pytest.raises(ValueError, match="records 6 trials"):
        replay_until_trial(tmp_path / JOURNAL, LiveModel(META), 6)


@pytest.fixture()
def server() -> Iterator[LiveServer]:
    """A live server of a small model on a free loopback port."""
    model = LiveModel(META)
    feed(model, 0, [10.0, 11.0, 12.0], 8.0)
    with LiveServer(model, port=0, push_interval_s=0.05) as live:
        yield live


def get(url: str, method: str = "GET", host: str | None = None) -> tuple[int, bytes]:
    """Status and body of one request."""
    request = urllib.request.Request(url, method=method)
    if host:
        request.add_header("Host", host)
    try:
        with urllib.request.urlopen(request, timeout=30) as answer:
            return answer.status, answer.read()
    except urllib.error.HTTPError as error:
        return error.code, error.read()


def test_server_is_read_only_and_serves_the_page(server: LiveServer) -> None:
    """GET only; the page and its files come from the package; foreign Host refused."""
    assert get(server.url)[0] == 200
    for name in ("live.js", "plot.js", "live.css"):
        assert get(server.url + "static/" + name)[0] == 200
    assert get(server.url + "static/../model.py")[0] == 404
    assert get(server.url + "api/state", method="POST")[0] == 405
    assert get(server.url + "api/state", method="DELETE")[0] == 405
    assert get(server.url + "api/state", host="evil.example:80")[0] == 403
    status, body = get(server.url + "api/state")
    assert status == 200 and json.loads(body)["trials"]["index"] == [0]
    assert bind_warning("127.0.0.1") is None and "SSH" in (bind_warning("0.0.0.0") or "")


def read_csv(path: Path) -> list[dict[str, str]]:
    """Rows of a CSV file."""
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def same_number(text: str, value: Any) -> bool:
    """A CSV cell and a JSON value hold the same number (or both NaN/None)."""
    if value is None:
        return text in ("nan", "")
    if isinstance(value, bool) or text in ("True", "False"):
        return text == str(bool(value))
    if isinstance(value, str):
        return text == value
    return float(text) == float(value) or (math.isnan(float(text)) and math.isnan(value))


def check_trials(trials: dict[str, list[Any]], csv_rows: list[dict[str, str]]) -> None:
    """Every trial the page got equals the trials.csv row of the same index."""
    assert trials["index"], "the page got no trials"
    for pos, index in enumerate(trials["index"]):
        row = csv_rows[index]
        for name in TRIAL_FIELDS:
            assert same_number(row[name], trials[name][pos]), (index, name)


def check_steps(trace: dict[str, Any], csv_rows: list[dict[str, str]]) -> None:
    """A trial's rows on the page equal its step log, column by column."""
    assert len(trace["rows"]) == len(csv_rows)
    for page_row, log_row in zip(trace["rows"], csv_rows, strict=True):
        for name, text in log_row.items():
            assert same_number(text, page_row[name]), name


def frames(stream: Any) -> Iterator[dict[str, Any]]:
    """The JSON frames of a server-sent-events stream until it ends."""
    data = []
    for raw in stream:
        line = raw.decode().rstrip("\n")
        if line.startswith("data: "):
            data.append(line[6:])
        elif line == "" and data:
            yield json.loads("\n".join(data))
            data = []


def start_live_run(out: Path, trials: int) -> tuple[subprocess.Popen[bytes], str]:
    """`forcelearn run --live --live-port 0` in a child process; its page URL."""
    child = subprocess.Popen(
        [
            *(sys.executable, "-c", CLI, "run", "--trials", str(trials), "--seed", "3"),
            *("--out", str(out), "--no-progress", "--live", "--live-port", "0"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert child.stderr is not None
    for raw in child.stderr:
        line = raw.decode()
        if line.startswith("live page: "):
            return child, line.split()[2]
    child.wait()
    raise AssertionError(f"no live page URL; exit {child.returncode}")


@pytest.mark.slow
def test_live_run_data_endpoint_equals_trials_csv_and_step_logs(tmp_path: Path) -> None:
    """While the run goes, the page's data equal what the run writes to its files."""
    out = tmp_path / "run"
    child, url = start_live_run(out, trials=6)
    trials: dict[str, list[Any]] = {name: [] for name in TRIAL_FIELDS}
    mid: dict[str, Any] | None = None
    last: dict[str, Any] = {}
    with urllib.request.urlopen(url + "api/events", timeout=120) as stream:
        for frame in frames(stream):
            since = frame["trials"]["since"]
            for name in TRIAL_FIELDS:
                trials[name] = trials[name][:since] + frame["trials"][name]
            status = frame["status"]
            if mid is None and status["trials_done"] >= 2 and not status["finished"]:
                status, body = get(url + "api/state")  # the data endpoint, mid-run
                assert status == 200
                mid = json.loads(body)
            last = frame
    assert child.wait(timeout=120) == 0, child.stderr.read().decode() if child.stderr else ""
    assert mid is not None and last["status"]["finished"]
    csv_trials = read_csv(out / "trials.csv")
    check_trials(mid["trials"], csv_trials)
    check_trials(trials, csv_trials)
    assert len(trials["index"]) == 6
    check_steps(mid["first"], read_csv(out / "steps_first.csv"))
    check_steps(last["previous"], read_csv(out / "steps_final.csv"))
    summary = json.loads((out / "summary.json").read_text())
    assert last["marks"]["phase_switch_trial"] == summary["phase_switch_trial"]
    assert last["marks"]["converged_trial"] == summary["converged_trial"]
    # The journal that `forcelearn view` follows holds the same run.
    model = LiveModel(META)
    JournalFollower(out / JOURNAL, model).read_available()
    replay = model.snapshot()
    check_trials(replay["trials"], csv_trials)
    check_steps(replay["previous"], read_csv(out / "steps_final.csv"))
    assert replay["status"]["finished"]


def test_view_of_a_run_without_journal_reads_its_csvs(tmp_path: Path) -> None:
    """Older runs and contour runs: trials.csv, summary.json and the step logs."""
    done = subprocess.run(
        [
            *(sys.executable, "-c", CLI, "sim", "contour", "--trials", "30", "--no-figures"),
            *("--no-progress", "--out", str(tmp_path)),
        ],
        capture_output=True,
        check=True,
    )
    assert done.returncode == 0
    state = load_run_directory(tmp_path).snapshot()
    check_trials(state["trials"], read_csv(tmp_path / "trials.csv"))
    check_steps(state["previous"], read_csv(tmp_path / "steps_final.csv"))
    assert state["status"]["finished"]
