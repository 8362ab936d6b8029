"""The Gymnasium environments: the checker, the API's episode ends, rendering, closing."""

from __future__ import annotations

import dataclasses
import itertools
import math

import gymnasium
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env

import forcelearn.envs
from forcelearn.envs import CONTOUR_ID, SURFACE_ID, ContourEnv, SurfaceEnv
from forcelearn.site import CellConfig
from forcelearn.tools.fuzz.fault_inject import shift_sensor_bias


def test_check_env_passes_for_the_contour_env() -> None:
    """Gymnasium's own checker (spaces, seeding, determinism, render) accepts §4."""
    env = ContourEnv(render_mode="rgb_array")
    check_env(env)
    env.close()


@pytest.mark.long
def test_check_env_passes_for_the_surface_env_on_the_emulated_cell() -> None:
    """The same checker accepts §5 through the real drivers."""
    env = SurfaceEnv(render_mode="rgb_array")
    try:
        check_env(env)
    finally:
        env.close()


def test_both_ids_are_registered_and_make_builds_the_classes() -> None:
    """`gymnasium.make` knows both ids once forcelearn.envs is imported."""
    gymnasium.register_envs(forcelearn.envs)
    env = gymnasium.make(CONTOUR_ID)
    assert isinstance(env.unwrapped, ContourEnv)
    env.close()
    assert SURFACE_ID in gymnasium.registry


def test_contour_rollout_holding_still_is_truncated_at_the_path_end() -> None:
    """No motion: 1 cm/step behind the desired velocity but in force, so r < 1 to the end."""
    env = ContourEnv()
    obs, info = env.reset(seed=0)
    assert obs.shape == (3,) and info["start_force_n"] == pytest.approx(0.7212, abs=1e-4)
    done, steps = False, 0
    while not done:
        obs, reward, terminated, truncated, info = env.step(np.zeros(2))
        steps += 1
        assert reward == pytest.approx(-info["r"])
        done = terminated or truncated
    assert (terminated, truncated, steps) == (False, True, 45)
    with pytest.raises(ResetNeeded):
        env.step(np.zeros(2))


def test_contour_rollout_pushing_into_the_disc_fails_and_terminates() -> None:
    """A full 5° step of θ2 drives the tip into the surface: r > 1, terminated, not truncated."""
    env = ContourEnv()
    env.reset(seed=0)
    for _ in range(45):
        _, reward, terminated, truncated, info = env.step(np.array([0.0, 1.0]))
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert info["failed"] and reward < -1.0


def test_surface_rollout_measures_force_spends_cell_time_and_renders() -> None:
    """A path 0.4 half-ranges below the probe's centre: −r per step, a drawn trace.

    The cell time grows; reset's info carries the probe's map and stiffness.
    """
    env = SurfaceEnv(render_mode="rgb_array")
    try:
        obs, info = env.reset(seed=3)
        assert obs[0] == 0.0 and obs[1] == pytest.approx(info["start_force_n"])
        choice = info["output_map"]
        assert choice["source"] == "probe" and choice == dataclasses.asdict(env.output_map)
        assert 1.0 < info["probe_stiffness_n_per_mm"] < 4.0  # the default sponge: 2 N/mm
        deeper = 0.4 * choice["max_offset_mm"]
        times, done = [], False
        while not done:
            obs, reward, terminated, truncated, info = env.step(np.array([-0.4]))
            tolerance = env.task_spec.tolerance
            assert reward == pytest.approx(-abs(info["force_n"] - 2 * 9.80665) / tolerance)
            assert info["y_cmd_mm"] == pytest.approx(choice["centre_y_mm"] - deeper)
            assert obs[2] == pytest.approx(-deeper)
            times.append(info["trial_cell_time_s"])
            done = terminated or truncated
        assert terminated != truncated
        assert info["step"] <= 20 and (truncated == (info["step"] == 20))
        assert all(b > a for a, b in itertools.pairwise(times)) and times[0] > 0
        frame = env.render()
        assert frame is not None and frame.shape == (240, 320, 3) and frame.dtype == np.uint8
        assert (frame < 200).any(), "the frame holds a drawing, not a blank canvas"
    finally:
        env.close()


def test_surface_reset_with_a_seed_opens_a_fresh_cell_and_without_keeps_the_wear(
    no_probe_config: CellConfig,
) -> None:
    """Same seed → same start; no seed → the same cell, one pass more worn."""
    env = SurfaceEnv(no_probe_config)
    try:
        _, first = env.reset(seed=1)
        env.step(np.array([-0.4]))
        _, again = env.reset(seed=1)
        assert again["start_force_n"] == first["start_force_n"]
        session = env.session
        env.reset()
        assert env.session is session
    finally:
        env.close()


def test_a_zero_that_moved_between_episodes_is_taken_again_in_free_space() -> None:
    """A sensor reading a 3 N pull on the way in: retract, zero in free space, press in again.

    (Before, the press guard's SensorSuspect ended a long baselines run: the JR3's drift
    over an untared run read -1.1 N above the sponge.)
    """
    env = SurfaceEnv()
    try:
        _, first = env.reset(seed=1)
        shift_sensor_bias(env.session, -3.0)
        _, again = env.reset()
        assert env.sensor_rezeros == 1
        assert abs(again["start_force_n"] - first["start_force_n"]) < 1.5  # half the step
    finally:
        env.close()


def test_close_stops_the_robot_releases_the_cell_and_is_idempotent(
    no_probe_config: CellConfig,
) -> None:
    """After close the env has no cell; stepping asks for a reset; a second close is harmless."""
    env = SurfaceEnv(no_probe_config)
    env.reset(seed=0)
    env.step(np.array([-0.3]))
    env.close()
    env.close()
    assert env.session is None
    with pytest.raises(ResetNeeded):
        env.step(np.array([0.0]))


def test_bad_arguments_are_refused_with_clear_errors() -> None:
    """Unknown render mode, non-finite actions, a config of the wrong type."""
    with pytest.raises(ValueError, match="render_mode"):
        ContourEnv(render_mode="human")
    with pytest.raises(TypeError, match="CellConfig"):
        SurfaceEnv(config=42)  # type: ignore[arg-type]
    env = ContourEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([math.nan, 0.0]))
