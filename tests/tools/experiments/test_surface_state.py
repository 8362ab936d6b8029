"""The run's checkpoint: the format written, older versions read, and the library's front door."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from forcelearn.errors import StateFileError
from forcelearn.learning import load_extra_arrays, load_learner
from forcelearn.site.config import load_cell_config
from forcelearn.tools.experiments.surface_state import (
    READABLE_VERSIONS,
    RUN_STATE_VERSION,
    SurfaceRun,
    restore,
    upgraded,
)

DATA = Path(__file__).parent / "data"
V5 = DATA / "checkpoint_v5"
"""Written by main 0362c01 (format version 5): ``forcelearn run --trials 2 --seed 0`` on the
default emulated cell; ``trials_main_4.csv`` is the same code's uninterrupted 4-trial run."""


def test_a_checkpoint_written_by_the_previous_code_resumes_bit_identical(tmp_path: Path) -> None:
    """Resumed to 4 trials through the front door, it ends as main's uninterrupted run did."""
    from forcelearn.runs import run_surface

    out = tmp_path / "old"
    out.mkdir()
    shutil.copyfile(V5 / "checkpoint.npz", out / "checkpoint.npz")
    summary = run_surface(out, trials=4, resume=True)
    assert summary["trials"] == 4
    resumed, main = (_trials_table(path) for path in (out / "trials.csv", V5 / "trials_main_4.csv"))
    assert resumed[0] == main[0]  # the same rows, columns, phases and failures
    # Bit-identical on the machine that wrote the fixture; numpy's SIMD kernels differ in the last
    # bit between CPUs (AVX2 against AVX-512), so across machines the figures agree to 1e-12.
    np.testing.assert_allclose(resumed[1], main[1], rtol=1e-12, atol=0.0)
    assert json.loads((out / "summary.json").read_text())["trials"] == 4


def _trials_table(path: Path) -> tuple[list[list[str]], np.ndarray]:
    """A trials.csv as its text columns (header, index, phase, steps, failed) and its figures."""
    rows = [line.split(",") for line in path.read_text().splitlines()]
    text = [rows[0]] + [row[:4] for row in rows[1:]]
    return text, np.array([[float(x) for x in row[4:]] for row in rows[1:]])


def test_the_front_door_refuses_what_a_resume_cannot_take(tmp_path: Path) -> None:
    """A resume keeps its own config and seed; a run needs at least one trial."""
    from forcelearn.runs import run_surface

    with pytest.raises(ValueError, match="own config and seed"):
        run_surface(tmp_path, seed=3, resume=True)
    with pytest.raises(ValueError, match="trials must be >= 1"):
        run_surface(tmp_path, trials=0)
    with pytest.raises(StateFileError, match="nothing to resume"):
        run_surface(tmp_path / "empty", resume=True)


def test_every_member_the_current_version_writes_is_filled_for_an_older_one() -> None:
    """upgraded() gives a version-4 file every member of today's metadata, as it ran."""
    state = load_learner(V5 / "checkpoint.npz")[1]
    assert state["run_state_version"] == RUN_STATE_VERSION
    later = ("map_recentre_mm", "tares", "learner_start", "wear_reference_n", "feasibility",
             "feasibility_now", "feasibility_first_trial")
    old = {k: v for k, v in state.items() if k not in later}
    old["run_state_version"] = 4
    filled = upgraded(old, desired_force_n=21.5)
    assert set(filled) == set(state)
    assert filled["learner_start"] == "cold" and filled["tares"] == (0, 0)
    assert filled["feasibility"] is None and filled["feasibility_now"] is False
    # the map tracked wear: the reference was the desired force then
    assert state["output_map"]["wear_stiffness_n_per_mm"] is not None
    assert filled["wear_reference_n"] == 21.5
    untracked = {**old, "output_map": {**old["output_map"], "wear_stiffness_n_per_mm": None}}
    assert upgraded(untracked, desired_force_n=21.5)["wear_reference_n"] is None
    assert upgraded(state, desired_force_n=21.5) == state  # today's file: nothing to fill


@pytest.mark.parametrize("version", [min(READABLE_VERSIONS) - 1, RUN_STATE_VERSION + 1, None])
def test_a_checkpoint_of_an_unknown_version_is_refused(tmp_path: Path, version: object) -> None:
    """Neither older than the oldest readable nor newer than the code: a StateFileError."""
    state = {**load_learner(V5 / "checkpoint.npz")[1], "run_state_version": version}
    run = SurfaceRun(load_cell_config(), trials=4, seed=0, out=tmp_path)
    arrays = load_extra_arrays(V5 / "checkpoint.npz")
    with pytest.raises(StateFileError, match="not a surface-run checkpoint of version"):
        restore(run, state, arrays)
    restore(run, {**state, "run_state_version": RUN_STATE_VERSION}, arrays)
    assert len(run.result.records) == len(run.traces) == 2
    assert not np.isnan(arrays["trace_force_n"]).any()  # every step's force kept
