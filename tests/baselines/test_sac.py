"""SAC (stable-baselines3) on the §5 env: opt-in, ``pytest -m baselines``."""

from __future__ import annotations

import pytest

from forcelearn.envs import SurfaceEnv

pytestmark = pytest.mark.baselines


def test_sac_trains_on_the_surface_env_and_is_scored_trial_by_trial() -> None:
    """A short SAC run: every episode it plays becomes a trial; the budget rule stops it."""
    pytest.importorskip("stable_baselines3", reason="needs pip install 'forcelearn[baselines]'")
    from forcelearn.baselines.sac import SACParams, run_sac

    env = SurfaceEnv(seed=0)
    try:
        recorder, model = run_sac(env, seed=0, trials=20, params=SACParams(learning_starts=10))
    finally:
        env.close()
    records = recorder.records
    assert len(records) == 20
    assert {r.phase for r in records} == {"sac"}
    assert model.num_timesteps == sum(r.steps + r.failed for r in records)
    assert model._n_updates > 0, "SAC learned (past its random warm-up)"
    assert all(r.cell_time_s > 0 for r in records)


def test_sac_trains_on_a_numpy_cell_of_the_vector_env() -> None:
    """The same run on SurfaceSimEnv (what the study's env = "vec" uses): scored the same way."""
    pytest.importorskip("stable_baselines3", reason="needs pip install 'forcelearn[baselines]'")
    from forcelearn.baselines.sac import SACParams, run_sac
    from forcelearn.envs.surface_vec import Probed, SurfaceSimEnv
    from forcelearn.site import load_cell_config
    from forcelearn.tasks.surface_map import configured_map

    env = SurfaceSimEnv(probed=Probed(configured_map(load_cell_config(None).task)))
    recorder, model = run_sac(env, seed=0, trials=20, params=SACParams(learning_starts=10))
    records = recorder.records
    assert len(records) == 20
    assert model.num_timesteps == sum(r.steps + r.failed for r in records)
    assert model._n_updates > 0
    assert all(r.cell_time_s > 0 for r in records)
