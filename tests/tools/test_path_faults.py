"""Faults in contact on the path task: judged from the emulator's physics, not the readings.

The cylinder example (the tool turning 50 deg over the arc), shortened to a few points a
pass. The truth is the part's contact force at the tool (``Truth`` of the fault campaign:
its largest magnitude over every physics tick, its zeros taken in contact).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import pytest

from forcelearn.paths.taught import rotation_from_wxyz
from forcelearn.site import CellSession
from forcelearn.tools.experiments import path_run
from forcelearn.tools.experiments.fault_recovery import read_events
from forcelearn.tools.experiments.path_state import prepare_path_run
from forcelearn.tools.experiments.records import read_records
from forcelearn.tools.fuzz.fault_inject import Truth
from forcelearn.tools.fuzz.fault_inject import shift_sensor_bias as shift_bias

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "paths" / "cylinder-cell.toml"


def cylinder_config(tmp_path: Path, points: int = 0, extra: str = "", task: str = "",
                    netft: bool = False) -> Path:
    """The cylinder example as a config file (realistic cell); ``points`` resamples the path.

    The example's 27 points (5 mm apart) by default: a straight move between two points of
    the convex arc dips L^2 / 8R = 0.02 mm into the foam, which no guard predicts (6 points,
    26 mm apart, dip 0.6 mm: 8 N more on a 15 N/mm foam, mid-move).
    """
    text = EXAMPLE.read_text()
    for name in ("cylinder-arc.csv", "emulated-jr3-cal.toml"):
        text = text.replace(f'"{name}"', f'"{EXAMPLE.parent / name}"')
    if netft:
        text = text.replace("emulated-jr3-cal.toml", "emulated-netft-cal.toml")
        extra = '[sensor]\nkind = "netft"\n' + extra
    text = text.replace('kind = "path"', f'kind = "path"\npoints_per_pass = {points}\n'
                        f'max_turn_deg = 12.0\n{task}')
    if points:
        text = text.replace("max_step_mm = 10.0", "max_step_mm = 30.0")
    file = tmp_path / "cell.toml"
    file.write_text(text + "\n" + extra)
    return file


class Watched:
    """The sessions a run opens, each with its :class:`Truth` and a hook on every reading."""

    def __init__(self) -> None:
        self.truths: list[Truth] = []
        self.sessions: list[CellSession] = []
        self.before_reading: Callable[[CellSession], None] | None = None

    def session_class(self) -> type[CellSession]:
        """A CellSession that registers itself here as it opens."""
        watched = self

        class Session(CellSession):
            def __init__(self, *args: Any, **kwargs: Any) -> None:
                super().__init__(*args, **kwargs)
                watched.sessions.append(self)
                watched.truths.append(Truth(self, tolerance_n=1.0))
                cell = self.cell
                assert cell is not None
                measure = cell.measure_force_n

                def measured(samples: int | None = None) -> float:
                    if watched.before_reading is not None:
                        watched.before_reading(self)
                    return measure(samples)

                cell.measure_force_n = measured  # type: ignore[method-assign]

        return Session

    @property
    def max_contact_n(self) -> float:
        """The largest true contact force of every session, N."""
        return max(t.max_contact_n for t in self.truths)


def run_watched(config: Path, out: Path, passes: int, watched: Watched) -> dict[str, Any]:
    """A new path run of ``passes`` passes on the watched sessions; its summary."""
    run, _ = prepare_path_run(config, None, out, passes, 0, 25, resume=False)
    with mock.patch.object(path_run, "CellSession", watched.session_class()):
        return path_run.execute(run, None, figures=False)


def true_along_axis_n(session: CellSession) -> float:
    """The part's force on the tool along the tool's force axis (into the part), N."""
    physics = session.physics
    assert physics is not None
    force = physics.environment.contact_force_world_n(physics._position_mm)
    quaternion = session.cell.pose.quaternion  # type: ignore[union-attr]
    axis = rotation_from_wxyz(np.array([quaternion])).apply(np.array([0.0, 0.0, 1.0]))[0]
    return float(-force @ axis)


def test_the_press_guard_keeps_a_stiff_part_under_the_limit(tmp_path: Path) -> None:
    """15 N/mm of foam (the guard's 20 N/mm unknown part), 25 N limit, 1 mm contact steps.

    Without the guard a contact step from ~10 N presses ~17 N more before anything is read;
    the guard (along each point's force axis) cuts it where the limit would be passed.
    """
    config = cylinder_config(
        tmp_path, task="tolerance_n = 2.0\n",
        extra="[emulator.sponge]\nstiffness_n_per_mm = 15.0\nstiffness_variation = 0.0\n")
    config.write_text(config.read_text().replace("max_force_n = 60.0", "max_force_n = 25.0"))
    watched = Watched()
    summary = run_watched(config, tmp_path / "run", 2, watched)
    assert summary["passes"] == 2
    assert summary["safety_this_session"]["press_guard_cuts"] > 0
    assert 20.0 < watched.max_contact_n <= 25.0


def test_every_pass_ends_with_a_zero_check_in_free_space_the_calibration_kept(
        tmp_path: Path) -> None:
    """The check at the turned end of a pass keeps the zero's calibration (no ToolMismatch).

    A software zero there used to re-derive the tool's weight for the end's orientation: the
    next pass's tare, back at the start, read the weight of a 50 deg turn (7.6 N on Fx) and
    raised ToolMismatch.
    """
    watched = Watched()
    summary = run_watched(cylinder_config(tmp_path, points=6), tmp_path / "run", 3, watched)
    assert summary["passes"] == 3 and summary["faults"]["count"] == 0
    truth = watched.truths[0]
    assert truth.zeros_in_contact == 0
    for trial in read_records(tmp_path / "run"):
        last = trial.tares[-1]  # the pass's zero check, after its retreat
        assert last.accepted and last.time_s >= trial.steps[-1].move.settled_s
        assert trial.steps[-1].stage == "retreat" and abs(last.reading_n) < 0.5


def test_a_zero_that_moved_during_a_pass_voids_it(tmp_path: Path) -> None:
    """A 1.5 N bias step in contact at pass 1's fourth point: the end's zero check voids it."""
    from forcelearn.tools.experiments.fault_recovery import VOIDED_FILE

    out = tmp_path / "run"
    watched = Watched()
    fired: list[int] = []

    def step_at_point_4(session: CellSession) -> None:
        if not fired and session.cell.stage == ("step", 4) and (  # type: ignore[union-attr]
                out / "checkpoint.npz").exists():
            fired.append(1)
            shift_bias(session, -1.5)  # reads less than it presses: not seen by the limit

    watched.before_reading = step_at_point_4
    summary = run_watched(cylinder_config(tmp_path, points=6), out, 2, watched)
    events = [(e["error"], e["action"], e["trial"]) for e in read_events(out)]
    assert fired and events == [("ZeroMoved", "voided", 1)]
    assert summary["passes"] == 2 and summary["faults"]["voided"] == 1
    voided = [json.loads(line) for line in (out / VOIDED_FILE).read_text().splitlines()]
    assert [(v["trial"], v["error"]) for v in voided] == [(1, "ZeroMoved")]
    assert not voided[0]["tares"][-1]["accepted"]  # the check that found it, kept with it


@pytest.mark.parametrize(("when", "expected"), [
    ("pass 0, first press", ("ZeroMoved", 0, "zero check")),
    ("pass 0, second press", ("SensorSuspect", 0, "pressed again at the same offset")),
    ("pass 1, first contact", ("SensorSuspect", 1, "where the last pass read")),
])
def test_a_bias_step_at_a_passes_first_contact_is_caught(
        tmp_path: Path, when: str, expected: tuple[str, int, str]) -> None:
    """A 6 N step down exactly at a pass's first contact (the first after its tare).

    Pass 0 (no earlier pass searched from its start) presses its first contact twice: a
    step at the first press shows in the zero check between the two (ZeroMoved); a step
    after that check, at the second press, makes it read 6 N less than the first
    (SensorSuspect). Pass 1 compares its first contact with pass 0's reading at the same
    offset (SensorSuspect). Either way the pass runs again from a zero taken in free space,
    and the true force never passes the limit.
    """
    out = tmp_path / "run"
    watched = Watched()
    fired: list[int] = []
    checks: list[int] = []
    in_pass = 1 if when.startswith("pass 1") else 0
    second = when.endswith("second press")

    def armed() -> bool:
        passes_done = (len(read_records(out)) if (out / "checkpoint.npz").exists() else 0)
        return not fired and (out / "probe.csv").exists() and passes_done == in_pass

    def at_first_contact(session: CellSession) -> None:
        if (armed() and (not second or len(checks) >= 2)
                and session.cell.stage == ("contact", 0)  # type: ignore[union-attr]
                and true_along_axis_n(session) > 0.25 * 19.6133):
            fired.append(1)
            shift_bias(session, -6.0)

    original = path_run.PathTask

    def counting_the_checks(*args: Any, **kwargs: Any) -> Any:
        task = original(*args, **kwargs)
        check = task.zero_check

        def checked() -> None:  # a pass's checks: after its tare, then between the presses
            check()
            if armed():
                checks.append(1)

        task.zero_check = checked
        return task

    watched.before_reading = at_first_contact
    run, _ = prepare_path_run(cylinder_config(tmp_path, points=6), None, out, 2, 0, 25,
                              resume=False)
    with mock.patch.object(path_run, "PathTask", counting_the_checks), \
            mock.patch.object(path_run, "CellSession", watched.session_class()):
        summary = path_run.execute(run, None, figures=False)
    events = [(e["error"], e["trial"], e["message"]) for e in read_events(out)]
    error, trial, says = expected
    assert fired and [(e, t) for e, t, _ in events] == [(error, trial)]
    assert says in events[0][2]
    assert summary["passes"] == 2
    assert watched.max_contact_n <= 60.0
    assert all(truth.zeros_in_contact == 0 for truth in watched.truths)


@pytest.mark.parametrize(("sensor", "stage"), [("jr3", ("step", 3)), ("netft", ("step", 3)),
                                               ("jr3", ("contact", 0))])
def test_a_sensor_reboot_mid_pass_never_presses_past_the_limit_nor_reads_off_after(
        tmp_path: Path, sensor: str, stage: tuple[str, int]) -> None:
    """A JR3 bootup or a Net F/T reboot in pass 1, the tool pressing the cylinder.

    At its third point, or at its first contact (between the two presses' readings).

    The truth (the emulator's physics): the contact force never passes [safety] max_force_n,
    no zero is taken in contact (the retract goes back along the tool's axis first), and every
    reading in contact after the reboot is within 3 sigma of one sample's noise of the true
    force along the tool's axis (nothing from before the reboot is used: the pass runs again).
    """
    out = tmp_path / "run"
    extra = ("" if sensor == "jr3" else
             '[sensor]\nkind = "netft"\nhost = "emulated"\ncalibration_source = "http"\n'
             'zero_on_init = true\n[filter]\nmeasurement_variance_n2 = 0.0025\n')
    config = cylinder_config(tmp_path, points=6, extra=extra)
    if sensor == "netft":
        config.write_text(config.read_text().replace("emulated-jr3-cal.toml",
                                                     "emulated-netft-cal.toml"))
    watched = Watched()
    fired: list[int] = []
    errors: list[float] = []

    def reboot_then_judge(session: CellSession) -> None:
        cell, emulator = session.cell, session.sensor_emulator
        assert cell is not None
        if fired and true_along_axis_n(session) > 0.25 * 19.6133:
            pending.append(true_along_axis_n(session))
        elif (not fired and cell.stage == stage and (out / "checkpoint.npz").exists()
              and true_along_axis_n(session) > 0.25 * 19.6133):  # pressing
            fired.append(1)
            (emulator.inject_bootup if sensor == "jr3" else emulator.inject_reboot)()

    pending: list[float] = []
    watched.before_reading = reboot_then_judge
    session_class = watched.session_class()

    class Judged(session_class):  # type: ignore[misc,valid-type]
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            measure = self.cell.measure_force_n  # type: ignore[union-attr]

            def judged(samples: int | None = None) -> float:
                pending.clear()
                reading = measure(samples)
                if pending:
                    errors.append(abs(reading - true_along_axis_n(self)))
                return reading

            self.cell.measure_force_n = judged  # type: ignore[method-assign,union-attr]

    run, _ = prepare_path_run(config, None, out, 2, 0, 25, resume=False)
    with mock.patch.object(path_run, "CellSession", Judged):
        summary = path_run.execute(run, None, figures=False)
    events = [(e["error"], e["action"], e["trial"]) for e in read_events(out)]
    assert fired and events == [("SensorRebooted", "resumed", 1)]
    assert summary["passes"] == 2
    session = watched.sessions[0]
    axis = session.cell.force_filter.config.axis  # type: ignore[union-attr]
    sigma_n = float(session.sensor_emulator.model.params.noise_std[axis])
    assert watched.max_contact_n <= 60.0
    assert watched.truths[0].zeros_in_contact == 0
    assert len(errors) >= 6 and max(errors) <= 3 * sigma_n


def test_a_software_zero_at_a_turned_pose_leaves_the_calibrated_bias(tmp_path: Path) -> None:
    """A software zero with the tool turned 40 deg keeps the calibration of the sensor's zero.

    ``Cell.check_zero`` used to re-derive it for the turned pose: off by the tool's weight.
    """
    from forcelearn.devices import Pose
    from forcelearn.site.config import load_cell_config

    config = load_cell_config(cylinder_config(tmp_path))
    with CellSession(config, seed=0) as session:
        cell = session.cell
        assert cell is not None and cell.calibration is not None
        cell.zero_in_free_space()
        here = cell.pose
        half = np.radians(40.0) / 2
        cell.move_to(Pose(here.x_mm, here.y_mm, here.z_mm,
                          (float(np.cos(half)), float(np.sin(half)), 0.0, 0.0)))
        calibration, compensation = cell.calibration, cell.compensation
        cell.check_zero(lambda std: 1e9)
        assert cell.calibration is calibration and cell.compensation is compensation
