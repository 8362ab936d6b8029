"""The emulated cell on its simulated clock: host-independent results, learning at any timing.

Each run here goes through the real drivers (a pty and a virtual CAN bus) to
the emulators, as ``forcelearn run`` does.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

from forcelearn.learning import SRVLearner
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.surface import SurfaceTask
from forcelearn.tools.experiments.surface_run import execute
from forcelearn.tools.experiments.surface_state import prepare_run
from forcelearn.trainer import TrainingResult, converged_trial, train

OUTPUTS = ("trials.csv", "steps_first.csv", "steps_final.csv")


def run_outputs(folder: Path, config_text: str | None = None, trials: int = 2) -> dict[str, str]:
    """Run ``trials`` trials (seed 3) in this process; return the result files' text."""
    config = None
    if config_text is not None:
        config = folder.with_suffix(".toml")
        config.write_text(config_text)
    run, _ = prepare_run(config, folder, trials, 3, resume=False)
    summary = execute(run, None)
    probed = ("probe.csv",) if (folder / "probe.csv").exists() else ()
    assert summary["cell_time_s"] > 0 and summary["realtime_factor"] > 0
    return {name: (folder / name).read_text() for name in (*OUTPUTS, *probed)}


def test_trials_record_the_cell_time_they_held(tmp_path: Path, configured_map_toml: str) -> None:
    """trials.csv carries each trial's cell time; the first includes the trip from home."""
    outputs = run_outputs(tmp_path / "run", configured_map_toml)  # no probe before trial 0
    rows = [line.split(",") for line in outputs["trials.csv"].splitlines()]
    column = rows[0].index("cell_time_s")
    times = [float(row[column]) for row in rows[1:]]
    assert times[0] > times[1] > 1.0  # the first trial travels 600 mm down in 10 mm moves


def test_pace_does_not_change_the_results(tmp_path: Path, configured_map_toml: str) -> None:
    """time_scale = 0 (as fast as possible) and 20 (paced to the wall clock) give equal files.

    Without the probe (a whole output map configured): at 20x its cell time alone would
    cost seconds; the probe's determinism is the loaded-host test's.
    """
    fast = run_outputs(tmp_path / "fast", configured_map_toml)
    paced = run_outputs(tmp_path / "paced", configured_map_toml + "[emulator]\ntime_scale = 20.0\n")
    assert paced == fast


SHORT_PROBE_TOML = "[probe]\npoints = [0.5]\nrefine_points = [0.0]\n"
"""A probe of one point and one refining point (the default has 3 + 4): the same reads,
presses, ease-offs and refinement, in under a third of the cell time."""


def test_a_loaded_host_does_not_change_the_results(tmp_path: Path) -> None:
    """Two CPU hogs beside the run (its probe, then its trials): the same bytes as idle."""
    idle = run_outputs(tmp_path / "idle", SHORT_PROBE_TOML)
    hogs = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)
    ]
    try:
        loaded = run_outputs(tmp_path / "loaded", SHORT_PROBE_TOML)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait(timeout=10)
    assert loaded == idle


CORNERS = [
    pytest.param(0.2, 50.0, 4800, id="laggy-slow-arm-slow-line"),
    pytest.param(0.01, 500.0, 19200, id="quick-arm-quick-line"),
]
"""Two corners of the range (20 mm/s arms are in the study: each costs minutes here)."""


@pytest.mark.convergence
@pytest.mark.parametrize(("lag_s", "speed_mm_s", "baudrate"), CORNERS)
def test_the_controller_learns_at_the_corners_of_the_timing_range(
    lag_s: float, speed_mm_s: float, baudrate: int
) -> None:
    """Servo lag 0.01-0.2 s, speed 50-500 mm/s, 4800-19200 baud: it converges (seed 1).

    The full grid over more seeds is the study in docs/results/surface-timing.md.
    """
    base = load_cell_config()
    arm = dataclasses.replace(base.emulator.arm, lag_s=lag_s, default_speed_mm_s=speed_mm_s)
    config: CellConfig = dataclasses.replace(
        base,
        robot=dataclasses.replace(base.robot, baudrate=baudrate),
        emulator=dataclasses.replace(base.emulator, arm=arm),
    )
    with CellSession(config, seed=1) as session:
        assert session.cell is not None
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
        learner = SRVLearner(task.grid, 1, config.learner, rng=1, output=task.output_map())
        result = TrainingResult()
        converged = None
        while converged is None and len(result.records) < 250:
            train(learner, task, 10, result=result)
            converged = converged_trial(
                result.records, config.task.steps_per_trial, config.task.desired_force_n
            )
    assert converged is not None, f"not converged in {len(result.records)} trials"
    assert converged <= 237
