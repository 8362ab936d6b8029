"""A run that meets a fault in contact leaves the part, re-zeroes and goes on.

Operator faults too: Ctrl-C while pressing retracts before the run exits; a second
Ctrl-C during that retract leaves the tool in contact but says so, and ``--resume``
then retracts before anything else. The truth is the emulated physics, not a reading.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.fault_recovery import IN_CONTACT_FILE, read_events
from forcelearn.tools.experiments.records import RECORDS_FILE, scan_records
from forcelearn.tools.fuzz.fault_campaign import cell_config, injecting
from forcelearn.tools.fuzz.fault_inject import Injector, Truth

TRIALS = 2
STEPS = 4


def _config(tmp_path: Path, cell: str = "link+jr3") -> Path:
    return cell_config(cell, tmp_path, TRIALS, STEPS, probe=False)


def _watch(on_burst: Callable[[Truth, Any], None]) -> tuple[Injector, list[Truth]]:
    """An injector with no planned fault that calls ``on_burst(truth, cell)`` before each burst."""
    injector = Injector({}, __import__("random").Random(0))
    attach = injector.attach

    def attached(session: Any, truth: Truth) -> None:
        attach(session, truth)
        cell, measure = session.cell, session.cell.measure_force_n

        def measured(samples: int | None = None) -> float:
            on_burst(truth, cell)
            return measure(samples)

        cell.measure_force_n = measured

    injector.attach = attached  # type: ignore[method-assign]
    return injector, []


def _run(config: Path | None, out: Path, injector: Injector, truths: list[Truth],
         resume: bool = False) -> dict[str, Any]:
    with injecting(injector, 1.0, truths):
        run, checkpoint = run_state.prepare_run(config, out, None, None if resume else 3, resume)
        return engine.execute(run, checkpoint)


def _trials_recorded_once(out: Path, trials: int) -> None:
    recorded = sorted(t.trial for t in scan_records(out / RECORDS_FILE).trials if t.trial >= 0)
    assert recorded == list(range(trials))


def test_a_sensor_reboot_mid_press_is_recovered_and_the_trial_runs_again(tmp_path: Path) -> None:
    """Reboot in the second trial's press: retract, re-zero in free space, trial 1 again."""
    state = {"done": False}

    def reboot_in_trial_1(truth: Truth, cell: Any) -> None:
        if not state["done"] and cell.stage[0] == "step" and truth.contact_n() > 0 \
                and len(read_events(tmp_path / "run")) == 0 and (tmp_path / "run" /
                                                                 run_state.CHECKPOINT).exists():
            state["done"] = True
            truth.session.sensor_emulator.inject_bootup()

    injector, truths = _watch(reboot_in_trial_1)
    summary = _run(_config(tmp_path), tmp_path / "run", injector, truths)
    assert state["done"]
    events = read_events(tmp_path / "run")
    assert [(e["error"], e["action"], e["trial"]) for e in events] == [
        ("SensorRebooted", "resumed", 1)
    ]
    assert events[0]["lost"] == "offsets"
    assert summary["faults"]["resumed"] == 1 and summary["trials"] == TRIALS
    truth = truths[0]
    assert truth.zeros_in_contact == 0 and truth.zeros >= 1
    assert not truth.bad_readings  # no reading after the reboot was off the true force
    _trials_recorded_once(tmp_path / "run", TRIALS)
    trials = {t.trial: t for t in scan_records(tmp_path / "run" / RECORDS_FILE).trials}
    # the re-zero opens the trial run again; its first press, with nothing to compare with
    # after the re-zero, is made twice from a zero checked before each; the zero check ends it
    tare, *checks = trials[1].tares
    assert tare.accepted and tare.position_mm[1] == pytest.approx(events[0]["retract_y_mm"])
    assert len(checks) == 3 and all(check.accepted for check in checks)
    assert [t.accepted for t in trials[0].tares] == [True] * 3  # the session's first: the same


def _interrupt_in_press(out: Path, times: int) -> Callable[[Truth, Any], None]:
    """Ctrl-C at the first burst in contact once trial 0 is checkpointed.

    With ``times`` 2, again at the retract's first move.
    """
    state = {"fired": 0}

    def on_burst(truth: Truth, cell: Any) -> None:
        if state["fired"] == 0 and cell.stage[0] == "step" and truth.contact_n() > 0 \
                and (out / run_state.CHECKPOINT).exists():
            state["fired"] = 1
            if times == 2:
                move = cell.move_to

                def interrupted_move(*args: Any, **kwargs: Any) -> None:
                    cell.move_to = move
                    raise KeyboardInterrupt

                cell.move_to = interrupted_move
            raise KeyboardInterrupt

    return on_burst


def test_ctrl_c_mid_press_retracts_before_the_run_exits(tmp_path: Path) -> None:
    """The first Ctrl-C: the robot leaves the part, then the run stops (and says so)."""
    injector, truths = _watch(_interrupt_in_press(tmp_path / "run", 1))
    with pytest.raises(KeyboardInterrupt):
        _run(_config(tmp_path), tmp_path / "run", injector, truths)
    assert truths[0].contact_n() == 0.0  # out of the part
    (event,) = read_events(tmp_path / "run")
    assert (event["action"], event["in_contact"]) == ("interrupted", False)
    assert not (tmp_path / "run" / IN_CONTACT_FILE).exists()


def test_a_second_ctrl_c_says_the_tool_is_in_contact_and_resume_retracts_first(
    tmp_path: Path,
) -> None:
    """Ctrl-C twice: the retract stops, the run says the tool presses; --resume retracts first."""
    out = tmp_path / "run"
    injector, truths = _watch(_interrupt_in_press(out, 2))
    with pytest.raises(KeyboardInterrupt):
        _run(_config(tmp_path), out, injector, truths)
    assert truths[0].contact_n() > 0.0  # really left in contact ...
    (event,) = read_events(out)
    assert event["in_contact"] and "may still press" in event["message"]  # ... and said so
    assert json.loads((out / IN_CONTACT_FILE).read_text())["error"] == "KeyboardInterrupt"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["faults"]["in_contact"]
    calls: list[str] = []
    watcher, watched = _watch(lambda truth, cell: calls.append(cell.stage[0]))
    _run(None, out, watcher, watched, resume=True)
    events = read_events(out)
    assert events[-1]["action"] == "retracted on resume"
    assert not (out / IN_CONTACT_FILE).exists()
    assert watched[0].zeros_in_contact == 0
