"""Surface-v0 and a zero that moves: a pull read in a step, the zero check at an episode's end.

Judged from the emulator's physics (the sponge's true force), not from the readings.
"""

from __future__ import annotations

import numpy as np

from forcelearn.envs import SurfaceEnv
from forcelearn.site import CellConfig
from forcelearn.tools.fuzz.fault_inject import shift_sensor_bias


def shift_bias(env: SurfaceEnv, reading_change_n: float) -> None:
    """Move the emulated JR3's bias so the normal force reads ``reading_change_n`` more."""
    assert env.session is not None and env.session.cell is not None
    shift_sensor_bias(env.session, reading_change_n)


def true_normal_n(env: SurfaceEnv) -> float:
    """The sponge's force on the tool along +Y now, N."""
    physics = env.session.physics  # type: ignore[union-attr]
    return float(physics.environment.contact_force_world_n(physics.pose.position_mm)[1])


def test_a_pull_read_in_a_step_retracts_zeroes_presses_in_and_makes_the_step_again(
        no_probe_config: CellConfig) -> None:
    """The zero moved 3 N down, then a step lifts the tool off the sponge: it reads -3 N.

    (Before, the press guard's SensorSuspect ended the episode: a cold run's drift.)
    """
    env = SurfaceEnv(no_probe_config)
    try:
        env.reset(seed=1)
        env.step(np.array([0.0]))
        shift_bias(env, -3.0)
        _, _, terminated, _, lifted = env.step(np.array([1.0]))  # 15 mm up: off the sponge
        assert lifted["sensor_rezeros"] == 1 and lifted["step"] == 2
        assert true_normal_n(env) == 0.0 and abs(lifted["force_n"]) < 0.5
        assert terminated and not lifted["zero_moved"]  # off the sponge: the paper's failure
        _, start = env.reset()  # pressing in again reads the truth
        assert abs(start["start_force_n"] - true_normal_n(env)) < 1.0
    finally:
        env.close()


def test_every_episode_ends_with_a_zero_check_and_a_moved_zero_is_reported(
        no_probe_config: CellConfig) -> None:
    """A fault-free episode's check is within its bound; a 2 N step mid-episode is not."""
    env = SurfaceEnv(no_probe_config)
    try:
        ends = []
        for episode in range(2):
            env.reset(seed=2 if episode == 0 else None)
            done, steps = False, 0
            while not done:
                steps += 1
                if episode == 1 and steps == 3:
                    shift_bias(env, 2.0)  # in contact: reads 2 N more, never a pull
                _, _, terminated, truncated, info = env.step(np.array([0.0]))
                done = terminated or truncated
            ends.append(info)
        assert not ends[0]["zero_moved"] and abs(ends[0]["zero_check_n"]) < 0.5
        assert ends[1]["zero_moved"] and abs(ends[1]["zero_check_n"] - 2.0) < 0.5
        assert (ends[0]["zero_voids"], ends[1]["zero_voids"]) == (0, 1)
        _, start = env.reset()  # zeroed in free space after the check: the truth again
        assert abs(start["start_force_n"] - true_normal_n(env)) < 1.0
    finally:
        env.close()
