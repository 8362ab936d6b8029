"""``forcelearn/SurfaceVec-v0``: paper §5 on N emulated cells at once, in numpy.

The same task as ``forcelearn/Surface-v0`` (observation, action, reward,
episode end: :class:`~forcelearn.envs.surface.SurfaceEnv`'s docstring), on
the physics of :mod:`forcelearn.envs.surface_batch` instead of the drivers and
the wires: thousands of times faster, for learning research. Its agreement
with the wire-level cell is measured (docs/results/surface-vec.md,
``tests/envs/test_surface_vec.py``).

::

    import gymnasium, forcelearn.envs
    envs = gymnasium.make_vec("forcelearn/SurfaceVec-v0", num_envs=64,
                              vectorization_mode="vector_entry_point")
    env = gymnasium.make("forcelearn/SurfaceVec-v0")   # one cell, a gymnasium.Env

The output map is the wire-level cell's: at construction one
``Surface-v0`` cell is opened with the config and the seed, the surface probe
runs on it (a few seconds) and its map (centre, scale, half-range, wear
tracking) and the sponge's passes after the probe start every cell here;
``probed=`` skips that (a probe run elsewhere, e.g. once for many envs).

Vector API: ``autoreset_mode`` NEXT_STEP (Gymnasium's default): the step
after a sub-env's episode ended resets it (reward 0, its action ignored).
``info`` holds arrays ``r``, ``force_n``, ``y_cmd_mm``, ``failed``, and
``start_force_n`` of the cells reset in that call. Randomness: one
``numpy.random.Generator`` for the batch, seeded by ``reset(seed=...)``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from forcelearn.envs.base import box
from forcelearn.envs.surface_batch import BatchSpec, SurfaceBatch
from forcelearn.envs.surface_learner import SurfaceLearnerAdapter
from forcelearn.site.jr3_kind import sensor_model
from forcelearn.tasks.surface_map import OutputMapChoice
from forcelearn.tasks.surface_probe import ProbeResult

NORMAL_AXIS = 1
"""The sensor axis of the sponge's normal force (``filter.axis``)."""


@dataclass(frozen=True)
class Probed:
    """What one wire-level cell's surface probe left: the map and the sponge's state."""

    output_map: OutputMapChoice
    passes: int = 0
    """The sponge's passes after the probe (each probe point is a press)."""
    cell_time_s: float = 0.0
    """Cell time from the sensor's zeroing to the first trial, s."""
    probe: ProbeResult | None = None
    """The probe's readings and fits (the warm start's input); None: no probe ran."""


def probe_map(config: Any, seed: int) -> Probed:
    """Open one wire-level cell (``Surface-v0``) with ``seed`` and run its surface probe."""
    from forcelearn.envs.surface import SurfaceEnv

    env = SurfaceEnv(config, seed=seed)
    try:
        env.reset(seed=seed)
        physics: Any = getattr(env.session, "physics", None)
        if physics is None:
            raise ValueError("the probe needs the emulated cell (the config opened a real one)")
        return Probed(env.output_map, int(physics.environment.passes),
                      float(physics.clock.now_s), env.probe)
    finally:
        env.close()


def batch_spec(config: Any, probed: Probed) -> BatchSpec:
    """The batch's spec from a cell config (``CellConfig``) and the map it runs with."""
    task, emulator, choice = config.task, config.emulator.effective(), probed.output_map
    sensor = sensor_model(config)  # the JR3's model, with the profile applied
    full_scale = float(sensor.full_scales[NORMAL_AXIS])
    _, start_y, start_z = task.start_mm
    return BatchSpec(
        sponge=emulator.sponge,
        motion=emulator.arm.motion_params(),
        evaluation=task.evaluation,
        max_force_n=config.safety.max_force_n,
        steps=task.steps_per_trial,
        z_step_mm=task.z_step_mm,
        start_y_mm=start_y,
        start_z_mm=start_z,
        retract_y_mm=task.retract_y_mm,
        settle_s=task.settle_s,
        samples=task.samples_for(config.filter.sample_period_s),
        sample_period_s=config.filter.sample_period_s,
        noise_std_n=float(sensor.noise_std[NORMAL_AXIS]),
        noise_cutoff_hz=float(config.filter.noise_cutoff_hz or 0.0),
        count_n=full_scale / 16384.0,
        bias_drift_n_per_sqrt_s=float(sensor.bias_drift_per_sqrt_s[NORMAL_AXIS]),
        filter_variance_n2=config.filter.measurement_variance_n2,
        move_change_std_n=config.filter.move_change_std_n,
        max_step_mm=config.safety.max_step_mm,
        centres_mm=tuple(choice.centre_at(k) for k in range(task.steps_per_trial)),
        max_offset_mm=choice.max_offset_mm,
        start_press_y_mm=start_y if choice.start_press_y_mm is None else choice.start_press_y_mm,
        wear_stiffness_n_per_mm=choice.wear_stiffness_n_per_mm,
        shift_range_mm=choice.shift_range_mm,
        passes_at_start=probed.passes,
        approach_mm=choice.approach_mm,
        bias_time_s=probed.cell_time_s,
    )


def _load(config: Any) -> Any:
    from forcelearn.site import CellConfig, load_cell_config

    if config is None or isinstance(config, str | Path):
        config = load_cell_config(config)
    if not isinstance(config, CellConfig):
        raise TypeError(f"config must be a CellConfig, a TOML path or None, got {config!r}")
    if config.robot_emulated is False or config.sensor_emulated is False or (
        type(config.robot).__name__ != "LinkConfig" or type(config.sensor).__name__ != "Jr3Config"
    ):
        raise ValueError("SurfaceVec-v0 emulates the default cell (computer link + JR3); "
                         "use forcelearn/Surface-v0 for this config")
    return config


class SurfaceVecEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """N §5 cells in numpy (see the module docstring); spaces are Surface-v0's, batched."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(
        self,
        num_envs: int = 64,
        config: Any | str | Path | None = None,
        seed: int | None = None,
        probed: Probed | None = None,
    ) -> None:
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.config = _load(config)
        self.default_seed = self.config.seed if seed is None else int(seed)
        self.probed = probe_map(self.config, self.default_seed) if probed is None else probed
        self.output_map = self.probed.output_map
        self.spec_ = batch_spec(self.config, self.probed)
        self.num_envs = num_envs
        task, limit = self.config.task, self.config.safety.max_force_n
        widest = task.retract_y_mm - self.config.safety.workspace_min_mm[1]
        self.single_action_space = box([-1.0], [1.0])
        self.single_observation_space = box([0.0, -limit, -widest], [task.path_mm, limit, widest])
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self._low = self.single_observation_space.low
        self._high = self.single_observation_space.high
        self._batch: SurfaceBatch | None = None
        self._offset = np.zeros(num_envs)
        self._needs_reset = np.zeros(num_envs, dtype=bool)

    def _observation(self, batch: SurfaceBatch) -> np.ndarray:
        obs = np.empty((self.num_envs, 3))
        np.multiply(batch.step_index, abs(self.spec_.z_step_mm), out=obs[:, 0])
        obs[:, 1] = batch.force
        obs[:, 2] = self._offset
        np.maximum(obs, self._low, out=obs)
        np.minimum(obs, self._high, out=obs)  # np.clip's bounds, at a third of its cost
        return obs

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """New sponges (as after the probe) for all cells, pressed in at the start."""
        if isinstance(seed, list):
            seed = seed[0]
        super().reset(seed=seed)
        rng = np.random.default_rng(self.default_seed if seed is None else seed)
        if self._batch is None or seed is not None:
            self._batch = SurfaceBatch(self.spec_, self.num_envs, rng)
        start = self._batch.reset()
        self._offset = np.zeros(self.num_envs)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        return self._observation(self._batch), {"start_force_n": start.copy()}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every cell; cells whose episode ended last step are reset instead."""
        batch = self._batch
        if batch is None:
            raise gymnasium.error.ResetNeeded("call reset() first")
        a = np.asarray(actions, dtype=float).reshape(self.num_envs)
        if not np.isfinite(a).all():
            raise ValueError(f"actions must be finite, got {actions!r}")
        resetting = self._needs_reset
        offset = np.minimum(np.maximum(a, -1.0), 1.0) * self.spec_.max_offset_mm
        offset[resetting] = 0.0
        self._offset = offset
        out = batch.advance(self._offset, resetting)  # ended cells start again instead
        info: dict[str, Any] = {"r": out["r"], "force_n": out["force_n"],
                                "y_cmd_mm": out["y_cmd_mm"], "failed": out["failed"]}
        if resetting.any():
            info["start_force_n"] = np.where(resetting, out["force_n"], np.nan)
        reward = -out["r"]
        terminated = out["failed"]
        truncated = out["done"] & ~terminated
        self._needs_reset = terminated | truncated
        return self._observation(batch), reward, terminated, truncated, info


class SurfaceSimEnv(SurfaceLearnerAdapter, gymnasium.Env[np.ndarray, np.ndarray]):
    """One cell of :class:`SurfaceVecEnv` as a ``gymnasium.Env`` (what ``gymnasium.make`` gives).

    Offers what ``Surface-v0`` offers a learner over BOXES (``grid``,
    ``learner_input``, ``learner_action``, ``output_map``, ``probe``) and the same
    ``reset`` info, so the baselines' controllers run on it unchanged.
    """

    metadata = {"render_modes": []}  # noqa: RUF012

    def __init__(self, config: Any | str | Path | None = None, seed: int | None = None,
                 probed: Probed | None = None) -> None:
        self._vec = SurfaceVecEnv(1, config, seed, probed)
        self.config = self._vec.config
        self.task_spec = self.config.task
        self.task_steps_per_trial = self.task_spec.steps_per_trial
        self.task_desired_force_n = self.task_spec.desired_force_n
        self.output_map = self._vec.output_map
        self.probe = self._vec.probed.probe
        self.action_space = self._vec.single_action_space
        self.observation_space = self._vec.single_observation_space
        self._done = True

    def _reset_info(self) -> dict[str, Any]:
        probe, spec = self.probe, self.task_spec
        centres = np.asarray(self._vec.spec_.centres_mm)
        return {
            "output_map": dataclasses.asdict(self.output_map),
            "probe_stiffness_n_per_mm": probe.stiffness_n_per_mm() if probe else None,
            "probe_path_mm": (probe.target_path_mm(spec) - centres).tolist() if probe else None,
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Return to the start pose (a new sponge when a seed is given)."""
        super().reset(seed=seed)
        batch = self._vec._batch
        if batch is None or seed is not None:
            obs, info = self._vec.reset(seed=seed)
        else:
            start = batch.reset()
            self._vec._offset = np.zeros(1)
            self._vec._needs_reset = np.zeros(1, dtype=bool)
            obs, info = self._vec._observation(batch), {"start_force_n": start.copy()}
        self._done = False
        return obs[0], {"start_force_n": float(info["start_force_n"][0]), **self._reset_info()}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One step; see ``Surface-v0``."""
        if self._done:
            raise gymnasium.error.ResetNeeded("the episode has ended: call reset() first")
        obs, reward, terminated, truncated, info = self._vec.step(np.asarray(action).reshape(1))
        batch = self._vec._batch
        assert batch is not None  # stepped
        self._done = bool(terminated[0] or truncated[0])
        failed = bool(info["failed"][0])
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), {
            "r": float(info["r"][0]), "force_n": float(info["force_n"][0]),
            "force_error_n": float(info["force_n"][0]) - self.task_desired_force_n,
            "y_cmd_mm": float(info["y_cmd_mm"][0]), "failed": failed,
            "step": int(batch.step_index[0]),
            "trial_cell_time_s": float(batch.cell_time_s[0]),
        }


__all__ = ["Probed", "SurfaceSimEnv", "SurfaceVecEnv", "batch_spec", "probe_map"]
