"""The comparison's methods and its scoring: SRV through the env equals the native trainer."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from forcelearn.baselines.controllers import (
    ForceController,
    ILCController,
    ILCParams,
    PathSearchController,
    PathSearchParams,
    SRVController,
    measured_stiffness,
    q_filter,
)
from forcelearn.baselines.runner import TrialRecorder, run_controller, should_stop
from forcelearn.emulators.physics.two_link_arm import ContourGeometry, TwoLinkContourCell
from forcelearn.envs import ContourEnv, SurfaceEnv
from forcelearn.learning import SRVLearner, SRVParams
from forcelearn.press_guard import PressGuard
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.contour import ContourTask, ContourTaskSpec
from forcelearn.tasks.surface import SurfaceTask, SurfaceTaskSpec
from forcelearn.tasks.surface_probe import SurfaceProbe, probe_and_map
from forcelearn.tasks.surface_warm_start import warm_start
from forcelearn.tasks.zero_check import check_zero
from forcelearn.trainer import TrialRecord, train

SPEC = SurfaceTaskSpec()
FAKE_ENV = SimpleNamespace(task_spec=SPEC)


def _same_records(
    native: list[TrialRecord],
    through_env: list[TrialRecord],
    rel: float = 1e-9,
    abs_n: float = 1e-12,
) -> None:
    assert len(native) == len(through_env)
    for a, b in zip(native, through_env, strict=True):
        assert (a.index, a.steps, a.failed) == (b.index, b.steps, b.failed)
        assert b.mean_r == pytest.approx(a.mean_r, rel=rel, abs=abs_n / 10.0)
        assert b.force_rms_n == pytest.approx(a.force_rms_n, rel=rel, abs=abs_n)
        assert b.start_force_n == pytest.approx(a.start_force_n, rel=rel, abs=abs_n)
        assert b.cell_time_s == pytest.approx(a.cell_time_s, rel=rel, nan_ok=True)


def test_srv_through_the_contour_env_gives_the_native_trainers_trials() -> None:
    """The same seed, the same 60 trials (steps, failures, r, force RMS) either way."""
    seed, trials = 4, 60
    task = ContourTask(TwoLinkContourCell(ContourGeometry()), ContourTaskSpec())
    learner = SRVLearner(task.grid, 2, SRVParams(), rng=seed, output=task.output_map())
    native = train(learner, task, trials).records
    env = ContourEnv()
    controller = SRVController(env, SRVParams(), seed)
    recorder = run_controller(env, controller, trials, seed, stop_early=False)
    _same_records(native, recorder.records)
    assert sum(r.steps for r in native) > trials, "the runs went past the first step"


def test_srv_through_the_surface_env_gives_the_native_trainers_trials() -> None:
    """§5 on the emulated cell (real drivers): the probe, its map and 4 trials agree to 1e-9.

    Each trial ends with the zero check in free space, as the env's episodes and the run's
    trials do.

    Since every emulated device answers in the driver's thread (no wall-clock
    dependence left on the path), the native run and the env's are the same
    computation; this held with three CPU hogs on the two cores. (It was
    compared to 1 % when the devices ran in threads and a loaded host shifted
    their timing.)
    """
    seed, trials = 2, 4
    config = load_cell_config(None)
    with CellSession(config, seed=seed) as session:  # as `forcelearn run` starts
        assert session.cell is not None
        guard = session.cell.press_guard = PressGuard(  # the run's and the env's press guard
            config.safety.max_force_n, config.task.press_stiffness_n_per_mm,
            session.cell.force_filter.measurement_variance_n2 ** 0.5)
        probe = SurfaceProbe(session.cell, config.task, config.probe,
                             config.safety.max_step_mm, config.safety.workspace_min_mm[1])
        result, choice = probe_and_map(probe, refine=True)  # the default warm start's probe
        assert result is not None
        guard.know(max(f.stiffness_n_per_mm for f in result.fits))
        output = choice.output()
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm, output)
        learner = SRVLearner(task.grid, 1, config.learner, rng=seed, output=output)
        assert result is not None
        warm_start(learner, result, config.task, output)
        cell = session.cell
        native = train(learner, task, trials,  # the env's (and the run's) zero check a trial
                       on_trial=lambda record, log, learner: check_zero(cell)).records
    assert result is not None and choice.source == "probe"
    env = SurfaceEnv(config)
    try:
        controller = SRVController(env, config.learner, seed, config.learner_start)
        recorder = run_controller(env, controller, trials, seed, stop_early=False)
        assert env.output_map == choice
        assert env.probe is not None
        assert env.probe.stiffness_n_per_mm() == result.stiffness_n_per_mm()
    finally:
        env.close()
    _same_records(native, recorder.records)
    assert all(r.cell_time_s > 1.0 for r in recorder.records)


def test_should_stop_after_convergence_plus_ten_or_at_the_budget() -> None:
    """Converged at trial 3 → stop once 3 + 10 + 10 trials are done; never → at the budget."""

    def record(i: int, rms: float) -> TrialRecord:
        return TrialRecord(i, "x", 20, False, 0.1, rms, 10.0)

    records = [record(i, 5.0 if i < 3 else 0.5) for i in range(22)]
    assert not should_stop(records, 300, 20, 19.61)
    records.append(record(22, 0.5))
    assert should_stop(records, 300, 20, 19.61)
    bad = [record(i, 5.0) for i in range(30)]
    assert not should_stop(bad, 31, 20, 19.61) and should_stop(bad, 30, 20, 19.61)


def test_stiffness_estimate_is_the_force_rise_per_mm_and_stays_sane() -> None:
    """(F1 − F0)/|probe|, clipped away from zero (a probe that met nothing)."""
    assert measured_stiffness(10.0, 18.0, -4.0) == pytest.approx(2.0)
    assert measured_stiffness(10.0, 9.0, -4.0) == pytest.approx(0.2)


def test_q_filter_keeps_a_constant_path_and_smooths_a_spike() -> None:
    """Zero-phase, unit DC gain, the ends padded."""
    flat = np.full(20, -5.0)
    assert np.allclose(q_filter(flat, (0.25, 0.5, 0.25)), flat)
    spike = np.zeros(5)
    spike[2] = 4.0
    assert q_filter(spike, (0.25, 0.5, 0.25)).tolist() == [0.0, 1.0, 2.0, 1.0, 0.0]


PROBED = {"output_map": {"max_offset_mm": 8.0}, "probe_stiffness_n_per_mm": 1.6}
"""reset's info after a probe: half-range 8 mm, stiffness 1.6 N/mm."""


def _play(
    controller, forces: list[float], start_force_n: float = 10.0, info: dict | None = None
) -> list[float]:
    """Feed a controller a trial of measured forces; return the offsets it commanded (mm).

    ``info``: extras of reset's info (none: no probe ran, the fallback map).
    """
    extras = info or {}
    controller.begin(np.zeros(3), {"start_force_n": start_force_n, **extras})
    half = extras.get("output_map", {}).get("max_offset_mm", SPEC.fallback_offset_mm)
    offsets = []
    for force in forces:
        offsets.append(float(controller.act(np.zeros(3))[0]) * half)
        controller.observe(
            np.zeros(3), {"force_n": force, "force_error_n": force - SPEC.desired_force_n}
        )
    return offsets


def test_ilc_raises_the_path_where_it_pressed_too_hard_and_lowers_it_where_too_soft() -> None:
    """P-type update with L = 0.5, no Q-filter: Δp = L e / k̂ per step."""
    ilc = ILCController(FAKE_ENV, ILCParams(learning_gain=0.5, q_weights=(0.0, 1.0, 0.0)))
    desired = SPEC.desired_force_n
    forces = [18.0] + [desired + 2.0] * 9 + [desired - 2.0] * 10  # k̂ = (18 - 10)/4 = 2 N/mm
    _play(ilc, forces)
    ilc.end(TrialRecord(0, "ilc", 20, False, 0.1, 2.0, 10.0))
    change = ilc.path_mm - (-4.0)
    assert change[1:10] == pytest.approx(0.5 * 2.0 / 2.0)
    assert change[10:] == pytest.approx(-0.5 * 2.0 / 2.0)


def test_force_control_corrects_y_against_the_error_and_forgets_between_trials() -> None:
    """Too much force raises Y; the next trial starts from the first guess again (no memory)."""
    pi = ForceController(FAKE_ENV)
    first = _play(pi, [18.0, 25.0, 25.0])  # probe, then pressing 5.4 N too hard
    assert first[0] == pytest.approx(-4.0)
    assert pi.stiffness_n_per_mm == pytest.approx(2.0)
    assert first[2] > first[1]
    second = _play(pi, [SPEC.desired_force_n] * 3, start_force_n=SPEC.desired_force_n)
    assert second == pytest.approx([-4.0, -4.0, -4.0])  # no error: it holds the first guess


def test_after_the_envs_probe_the_methods_start_at_the_map_centre_with_its_stiffness() -> None:
    """PI and ILC take k̂ from the probe, start at offset 0 and stay in its half-range."""
    desired = SPEC.desired_force_n
    pi = ForceController(FAKE_ENV)
    offsets = _play(pi, [desired + 3.2, desired + 3.2], info=PROBED)
    assert pi.stiffness_n_per_mm == pytest.approx(1.6)
    assert offsets[0] == 0.0
    kp, ki = pi.params.kp, pi.params.ki
    assert offsets[1] == pytest.approx((kp + ki) * 3.2 / 1.6)  # Y rises: too much force
    ilc = ILCController(FAKE_ENV, ILCParams(learning_gain=0.5, q_weights=(0.0, 1.0, 0.0)))
    assert _play(ilc, [desired + 80.0] * 20, info=PROBED) == [0.0] * 20
    ilc.end(TrialRecord(0, "ilc", 20, False, 0.1, 2.0, 10.0))
    assert ilc.path_mm == pytest.approx(np.full(20, 8.0))  # 0.5 · 80 / 1.6 = 25, clipped to 8
    search = PathSearchController(FAKE_ENV, seed=0, params=PathSearchParams(popsize=4))
    _play(search, [desired] * 20, info=PROBED)
    assert np.allclose(search.es.mean, 0.0)
    assert np.all(np.abs(search.path_mm) <= 8.0)


def test_path_search_step_size_is_a_share_of_the_band_over_the_probes_stiffness() -> None:
    """σ0 = 0.4 · tolerance / k̂: the same force spread on any sponge; fixed without a probe.

    On the default cell (9.8 N, about 2 N/mm) that is 2 mm; a stiffer sponge gets
    a smaller step, a softer one a larger step (never past the map's half-range).
    """
    tolerance = SPEC.tolerance
    for stiffness in (0.3, 0.9, 1.6, 4.0):
        search = PathSearchController(FAKE_ENV, seed=0)
        info = {**PROBED, "probe_stiffness_n_per_mm": stiffness}
        _play(search, [SPEC.desired_force_n] * 20, info=info)
        expected = min(0.4 * tolerance / stiffness, 8.0)
        assert search.sigma0_mm == pytest.approx(expected)
        assert search.es.sigma0 == pytest.approx(expected)
    blind = PathSearchController(FAKE_ENV, seed=0)
    _play(blind, [SPEC.desired_force_n] * 20)
    assert blind.sigma0_mm == 2.0
    fixed = PathSearchController(FAKE_ENV, seed=0, params=PathSearchParams(sigma0_mm=0.7))
    _play(fixed, [SPEC.desired_force_n] * 20, info=PROBED)
    assert fixed.sigma0_mm == 0.7


def test_path_search_evaluates_one_candidate_per_trial_and_tells_a_full_generation() -> None:
    """Four candidates, one per trial; the mean moves once the generation is told."""
    search = PathSearchController(FAKE_ENV, seed=0, params=PathSearchParams(popsize=4))
    paths = []
    mean_before = np.full(20, -4.0)  # no probe: the operator's first guess
    for trial in range(4):
        _play(search, [SPEC.desired_force_n + trial] * 20)
        if trial == 0:
            assert np.allclose(search.es.mean, mean_before)
        paths.append(search.path_mm.copy())
        search.end(TrialRecord(trial, "cma", 20, False, 0.1, 1.0, 10.0))
    assert len({tuple(p) for p in paths}) == 4
    assert search.es.countiter == 1
    assert not np.allclose(search.es.mean, mean_before)


def test_recorder_scores_any_agent_by_the_trainers_formulas() -> None:
    """A random agent on §4: each record's RMS and steps follow from its episode's infos."""
    env = TrialRecorder(ContourEnv(), "random")
    env.action_space.seed(0)
    errors: list[float] = []
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        errors.append(info["force_error_n"])
        done = terminated or truncated
    (record,) = env.records
    assert record.force_rms_n == pytest.approx(float(np.sqrt(np.mean(np.square(errors)))))
    assert record.steps == len(errors) - (1 if record.failed else 0)
    assert record.phase == "random"


@pytest.mark.convergence
def test_ilc_converges_on_the_emulated_cell(tmp_path: Path) -> None:
    """ILC through the env meets the convergence rule on the default cell within 40 trials."""
    from forcelearn.tools.study.baselines import BaselinesConfig, run_baseline

    summary, curves = run_baseline(BaselinesConfig(method="ilc", trials=40), seed=0)
    assert summary["converged_trial"] is not None
    assert summary["trials_run"] == summary["converged_trial"] + 20
    assert summary["final_force_rms_n"] <= 0.05 * SPEC.desired_force_n
    assert len(curves["force_rms_n"]) == summary["trials_run"]
    assert summary["cell_time_to_converge_s"] > 0
