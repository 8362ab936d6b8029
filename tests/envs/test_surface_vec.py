"""forcelearn/SurfaceVec-v0: Gymnasium's checker, the vector API, and agreement with the wires."""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import forcelearn.envs
from forcelearn.envs.surface_vec import Probed, SurfaceSimEnv, SurfaceVecEnv
from forcelearn.site import load_cell_config
from forcelearn.tasks.surface_map import configured_map


def _probed() -> Probed:
    """The configured (fallback) map of the default cell: no wire-level probe needed."""
    return Probed(configured_map(load_cell_config(None).task))


def test_the_one_cell_env_passes_gymnasiums_checker() -> None:
    """check_env on what gymnasium.make("forcelearn/SurfaceVec-v0") gives."""
    env = SurfaceSimEnv(probed=_probed())
    check_env(env, skip_render_check=True)


def test_make_vec_gives_the_numpy_vector_env_with_batched_spaces() -> None:
    """make_vec with the vector entry point: N cells, Surface-v0's spaces batched."""
    forcelearn.envs.register_envs()
    envs = gymnasium.make_vec(forcelearn.envs.SURFACE_VEC_ID, num_envs=5,
                              vectorization_mode="vector_entry_point", probed=_probed())
    assert isinstance(envs.unwrapped, SurfaceVecEnv)
    obs, info = envs.reset(seed=3)
    assert obs.shape == (5, 3) and envs.observation_space.contains(obs)
    assert info["start_force_n"].shape == (5,)
    assert envs.action_space.shape == (5, 1)


def test_an_ended_episode_resets_at_the_next_step_with_no_reward() -> None:
    """Autoreset NEXT_STEP: the step after a done returns the start and reward 0."""
    envs = SurfaceVecEnv(3, probed=_probed())
    envs.reset(seed=0)
    pressing = np.full((3, 1), -1.0)  # as deep as the map allows: the force passes tolerance
    done = np.zeros(3, dtype=bool)
    for _ in range(envs.spec_.steps):
        _, _, terminated, truncated, _ = envs.step(pressing)
        done = terminated | truncated
        if done.any():
            break
    assert done.any()
    obs, reward, terminated, truncated, info = envs.step(pressing)
    assert np.all(reward[done] == 0.0) and not (terminated[done] | truncated[done]).any()
    assert np.all(obs[done, 0] == 0.0) and np.all(obs[done, 2] == 0.0)
    assert np.isfinite(info["start_force_n"][done]).all()
    assert np.isnan(info["start_force_n"][~done]).all()


def test_seeded_resets_repeat_and_seeds_differ() -> None:
    """The same seed gives the same forces; another seed other noise."""
    def forces(seed: int) -> np.ndarray:
        envs = SurfaceVecEnv(4, probed=_probed())
        envs.reset(seed=seed)
        return np.array([envs.step(np.zeros((4, 1)))[4]["force_n"] for _ in range(5)])

    assert np.array_equal(forces(1), forces(1))
    assert not np.array_equal(forces(1), forces(2))


@pytest.mark.convergence
@pytest.mark.parametrize("policy", ["fixed", "pi", "srv"])
def test_the_numpy_cells_agree_with_the_wire_level_cell_over_ten_seeds(policy: str) -> None:
    """Fixed path, PI, warm-started learner: per-trial force RMS within the wires' noise."""
    from forcelearn.tools.results.surface_vec import agreement, run_both

    results = [run_both(seed, (policy,), 3) for seed in range(10)]
    wire = np.array([r[policy]["wire"][0] for r in results])
    vec = np.array([r[policy]["numpy"][0] for r in results])
    largest, pooled = agreement(wire, vec)
    assert largest <= 2.0 * pooled, (largest, pooled)


def test_a_method_runs_trial_by_trial_on_one_numpy_cell_with_the_cells_clock() -> None:
    """ILC through SurfaceSimEnv: one record per trial, each with the cell time it took."""
    from forcelearn.baselines.controllers import ILCController
    from forcelearn.baselines.runner import run_controller
    from forcelearn.envs.surface_batch import RESET_TRAVEL_S

    env = SurfaceSimEnv(probed=_probed())
    ilc = ILCController(env)
    records = run_controller(env, ilc, 4, seed=0, stop_early=False).records
    assert len(records) == 4
    assert all(r.cell_time_s > RESET_TRAVEL_S + r.steps * env.task_spec.settle_s for r in records)


@pytest.mark.long
def test_without_sensor_noise_a_fixed_path_reads_the_wire_cells_forces_within_its_noise(
    tmp_path: Path,
) -> None:
    """One probed wire-level cell, its numpy twin from the same probe, the probe's path.

    With the JR3's noise and drift off, both are deterministic: every step's force
    of the numpy cell is within the default sensor's noise (one standard deviation of
    the normal axis) of the wire-level cell's. The probe on a noiseless sensor also
    fits a hysteresis, so each step approaches from above (two moves) on both.
    """
    from forcelearn.envs.surface import SurfaceEnv
    from forcelearn.site.jr3_kind import sensor_model
    from forcelearn.tools.results.surface_vec import FixedPath

    noise_n = float(sensor_model(load_cell_config(None)).noise_std[1])
    quiet = tmp_path / "quiet.toml"
    quiet.write_text("[emulator.sensor]\nnoise_std = [0, 0, 0, 0, 0, 0]\n"
                     "bias_drift_per_sqrt_s = [0, 0, 0, 0, 0, 0]\n")
    config = load_cell_config(quiet)

    def forces(env: gymnasium.Env[np.ndarray, np.ndarray], seeded: bool) -> np.ndarray:
        obs, info = env.reset(seed=0) if seeded else env.reset()
        path = FixedPath(env)
        path.begin(obs, info)
        out, done = [], False
        while not done:
            obs, _, terminated, truncated, step = env.step(path.act(obs))
            out.append(step["force_n"])
            done = terminated or truncated
        return np.array(out)

    wire = SurfaceEnv(config, seed=0)
    try:
        wire.reset(seed=0)
        physics = wire.session.physics  # type: ignore[union-attr]
        probed = Probed(wire.output_map, int(physics.environment.passes),
                        float(physics.clock.now_s), wire.probe)
        assert probed.output_map.approach_mm > 0.0
        on_wires = forces(wire, seeded=False)
    finally:
        wire.close()
    in_numpy = forces(SurfaceSimEnv(config, seed=0, probed=probed), seeded=True)
    assert len(on_wires) == len(in_numpy) == config.task.steps_per_trial
    assert np.abs(in_numpy - on_wires).max() <= noise_n
