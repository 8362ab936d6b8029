"""Surface-v0 and a zero that moves: a pull read in a step.

Judged from the emulator's physics (the sponge's true force), not from the readings.
"""

from __future__ import annotations

import numpy as np

from forcelearn.envs import SurfaceEnv
from forcelearn.site import CellConfig


def shift_bias(env: SurfaceEnv, reading_change_n: float) -> None:
    """Move the emulated JR3's bias so the normal force reads ``reading_change_n`` more."""
    session = env.session
    assert session is not None and session.cell is not None
    model = session.emulated_cell.sensor.emulator.model
    normal = session.cell.force_filter.config
    state = model.state_dict()
    bias = np.asarray(state["bias"], dtype=float)
    bias[normal.axis] += normal.sign * reading_change_n
    state["bias"] = bias
    model.load_state_dict(state)


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
        assert terminated  # off the sponge: the paper's failure
        _, start = env.reset()  # pressing in again reads the truth
        assert abs(start["start_force_n"] - true_normal_n(env)) < 1.0
    finally:
        env.close()
