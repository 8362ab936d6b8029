"""``forcelearn/Surface-v0``: paper §5, the roller on the sponge, through the real drivers.

By default the cell is the emulated one (the robot-controller emulator and the
JR3 emulator reached through the real computer-link and JR3 drivers, over the
in-process routes: ``forcelearn-robot://`` and a ``forcelearn-jr3`` bus, the
same bytes and frames as a pty and a CAN bus; one simulated clock).
``config="site.toml"`` drives a real cell.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.devices import Pose
from forcelearn.envs.base import TaskEnv, box
from forcelearn.envs.surface_learner import SurfaceLearnerAdapter
from forcelearn.errors import SensorSuspect
from forcelearn.press_guard import PressGuard
from forcelearn.tasks.recovery import retract_and_retare
from forcelearn.tasks.surface import SurfaceTask
from forcelearn.tasks.surface_map import OutputMapChoice, SurfaceYOutput, configured_map
from forcelearn.tasks.surface_probe import ProbeResult, SurfaceProbe, probe_and_map
from forcelearn.tasks.zero_check import check_zero

log = logging.getLogger(__name__)


class SurfaceEnv(SurfaceLearnerAdapter, TaskEnv):
    """Paper §5: press a roller into a sponge with 2 kgf while moving down 5 mm per step.

    ## Description
    A position-controlled robot holds a roller against a sponge; each step
    moves the tool 5 mm down (−Z) and to the commanded Y (normal to the
    sponge, + is away from it); the force is the JR3 reading through the
    Kalman filter after the robot is in position and has settled. The sponge
    varies along the path, relaxes after a press and wears with every pass,
    so the best Y path drifts from trial to trial. Task:
    ``forcelearn.tasks.surface``; cell: ``forcelearn.cell``; devices:
    ``forcelearn.site.session``.

    ## Output map (the same as ``forcelearn run``'s)
    When a cell is opened (the first reset, and every seeded reset on the
    emulated cell) the surface probe runs first, exactly as ``forcelearn run``
    starts (docs/surface.md): it finds the contact and the stiffness and
    chooses the map's centre Y (where the desired force is expected), its
    half-range and the learner's scale; with ``[run] learner_start = "probe"``
    (the default) it also probes its refine points, so ``probe_path_mm`` has
    the surface's waves. ``[probe] enabled = false`` or a fully
    configured map (``task.output_centre_y_mm``, ``output_scale_mm``,
    ``max_offset_mm``) skip it; the map is then the configured one, or the
    fallback (start Y, 2 mm, 15 mm). ``env.output_map`` holds it and
    ``reset``'s info carries it (``output_map``, a dict in mm) with the probe's
    stiffness (``probe_stiffness_n_per_mm``) and its surface model as a path
    (``probe_path_mm``: per step, the Y offset from the centre where the fits
    give the desired force), both ``None`` without a probe.

    ## Action space: ``Box(-1, 1, (1,), float64)``
    | index | meaning | unit after scaling |
    |---|---|---|
    | 0 | Y offset from the map's centre | ± the map's half-range, mm |

    Actions outside [-1, 1] are clipped. Y = centre + half-range · action.

    ## Observation space: ``Box(float64, (3,))``
    | index | meaning | unit | bounds |
    |---|---|---|---|
    | 0 | distance travelled along the path before the next step | mm | [0, 100] |
    | 1 | filtered normal force after the last move (after reset: at the start pose) | N | ± 60 |
    | 2 | last Y command relative to the map's centre (0 after reset) | mm | ± D |

    The force bound is ``safety.max_force_n``; D, the widest half-range any
    map can have, is the retract plane's height above the workspace floor
    (``task.retract_y_mm`` − ``safety.workspace_min_mm[1]``). Observations are
    clipped to the bounds.

    ## Reward
    −r with r = |force − 19.61 N| / tolerance (``task.tolerance_n``, default half the
    desired force).

    ## Start state
    The tool retracts, travels clear of the sponge and presses in at the start
    pose (900, −4, 0) mm; ``info["start_force_n"]`` is the force measured there
    (it falls as the sponge wears). ``reset(seed=s)`` on the emulated cell opens
    a *fresh* cell (new sponge, sensor noise seeded with s); ``reset()`` without
    a seed keeps the cell and its wear. On a real cell the seed reopens nothing.

    ## Episode end
    * terminated: |force error| > 10 N, or the safety force limit stopped the
      robot (r = 2), the paper's failure; the tool retracts;
    * truncated: 20 steps done without failure (the path's end).

    ## Faults in contact (docs/on-site.md)
    A zero that moved shows as a pull (the press guard's
    :class:`~forcelearn.errors.SensorSuspect`: a part never pulls the tool, e.g. the
    sensor's drift read with the tool lifted off the sponge). In ``reset`` or in a
    ``step`` the env does what the cell does: the tool retracts to the retract plane,
    the sensor is zeroed in free space, the tool presses in again (to where the step
    began) and the reset or step is made again, once; ``info["sensor_rezeros"]``
    (every step's) counts them since the env was made. With ``[task] zero_check`` (on
    by default) every episode ends, the tool retracted, with a zero check in free space
    (:mod:`forcelearn.tasks.zero_check`): the last step's info holds ``zero_check_n``
    (the reading, N), ``zero_moved`` (beyond 5 sigma of a fault-free check, twice: the
    episode's readings were off; the sensor is then zeroed there) and ``zero_voids``
    (episodes ended with a moved zero since the env was made). Within the bound the
    check's mean is the zero (the drift is taken away every episode).

    ## Arguments
    ``config``: a ``CellConfig``, or the path of a cell TOML (``None``: the
    emulated default, docs/surface.md); ``seed``: sensor-noise seed used when
    the first reset gives none; ``render_mode``: ``None`` or ``"rgb_array"``
    (the force trace of the episode); ``routes``: how the emulated devices are
    reached, kind name -> route option (``{"computer_link": LinkRoute("pty"),
    "jr3": Jr3Route("virtual")}``, from ``forcelearn.site.computer_link_kind``
    and ``forcelearn.site.jr3_kind``: a pty and a python-can ``virtual`` bus
    served by the emulators' threads, as a real cell's ports are; default: in
    process, the same bytes). ``close()`` stops the robot and closes the devices.
    """

    def __init__(
        self,
        config: Any | str | Path | None = None,
        seed: int | None = None,
        render_mode: str | None = None,
        routes: dict[str, object] | None = None,
    ):
        super().__init__(render_mode)
        # The devices live in the drivers/tools folders; imported here so the core
        # package does not import them at module level (docs/architecture.md).
        from forcelearn.site import CellConfig, load_cell_config

        if config is None or isinstance(config, str | Path):
            config = load_cell_config(config)
        if not isinstance(config, CellConfig):
            raise TypeError(f"config must be a CellConfig, a TOML path or None, got {config!r}")
        self.config = config
        self.task_spec = config.task
        self.default_seed = config.seed if seed is None else int(seed)
        self.routes = dict(routes or {})
        """Kind name -> route option of the emulated devices (empty: in process)."""
        self.session: Any | None = None
        self.output_map: OutputMapChoice = configured_map(config.task)
        """The output map of the open cell (before the first reset: the configured one)."""
        self._output: SurfaceYOutput = self.output_map.output(abs(config.task.z_step_mm))
        """Its output function, with the wear it tracks (the task moves its shift)."""
        self.probe: ProbeResult | None = None
        """What the latest probe read and fitted (``None``: no probe ran)."""
        self._y_offset_mm = 0.0
        self.sensor_rezeros = 0
        """Zeros taken again in free space after a pull (:meth:`reset`, :meth:`step`)."""
        self.zero_voids = 0
        """Episodes whose end's zero check found the zero moved."""
        spec, limit = self.task_spec, config.safety.max_force_n
        self.task_steps_per_trial = spec.steps_per_trial
        self.task_desired_force_n = spec.desired_force_n
        self.action_space = box([-1.0], [1.0])
        widest = spec.retract_y_mm - config.safety.workspace_min_mm[1]
        self.observation_space = box([0.0, -limit, -widest], [spec.path_mm, limit, widest])

    @property
    def emulated(self) -> bool:
        """True when the robot or the sensor is the built-in emulator."""
        return bool(self.config.robot_emulated or self.config.sensor_emulated)

    def _needs_new_task(self, seed: int | None) -> bool:
        return self.task is None or (seed is not None and self.emulated)

    def _open_task(self, seed: int | None) -> SurfaceTask:
        from forcelearn.site import CellSession

        config = self.config
        self.session = CellSession(config, seed=self.default_seed if seed is None else seed,
                                   routes=self.routes)
        cell = self.session.cell
        assert cell is not None  # opened, or CellSession raised
        cell.press_guard = PressGuard(config.safety.max_force_n,
                                      config.task.press_stiffness_n_per_mm,
                                      cell.force_filter.measurement_variance_n2 ** 0.5)
        probe = SurfaceProbe(
            cell, config.task, config.probe, config.safety.max_step_mm,
            config.safety.workspace_min_mm[1],
        )
        self.probe, self.output_map = probe_and_map(
            probe, refine=config.learner_start == "probe"
        )
        if self.probe is not None and self.probe.fits:  # the part's stiffness is known
            cell.press_guard.know(max(f.stiffness_n_per_mm for f in self.probe.fits))
        self._output = self.output_map.output(abs(self.task_spec.z_step_mm))
        return SurfaceTask(cell, self.task_spec, config.safety.max_step_mm, self._output)

    def _reset_info(self) -> dict[str, Any]:
        probe, choice = self.probe, self.output_map
        centres = np.array(
            [self._output.centre_of_step(k) for k in range(self.task_spec.steps_per_trial)]
        )
        return {
            "output_map": dataclasses.asdict(choice),
            "probe_stiffness_n_per_mm": probe.stiffness_n_per_mm() if probe else None,
            "probe_path_mm": (
                (probe.target_path_mm(self.task_spec) - centres).tolist() if probe else None
            ),
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Retract, return to the start pose, press in; see the class docstring.

        A zero that moved on the way in (:class:`~forcelearn.errors.SensorSuspect`: the
        press guard read a pull, e.g. the sensor's drift over a long run without a tare)
        is handled as a cell does: the tool retracts to free space, the sensor is zeroed
        there and the start press made again, once (``sensor_rezeros`` counts them).
        """
        self._y_offset_mm = 0.0
        try:
            return super().reset(seed=seed, options=options)
        except SensorSuspect as exc:
            cell = None if self.session is None else self.session.cell
            if cell is None:
                raise
            log.warning("%s: retracting, zeroing in free space and pressing in again", exc)
            retract_and_retare(cell, self.task_spec.retract_y_mm, self.config.safety.max_step_mm)
            self.sensor_rezeros += 1
            return super().reset(seed=None, options=options)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control step (:class:`TaskEnv`); a pull read on the way is recovered from once.

        The episode's last step ends with the zero check (the class docstring).
        """
        task = self.task
        cell = None if self.session is None else self.session.cell
        before = None if cell is None else cell.known_pose
        counters = None if not isinstance(task, SurfaceTask) else (task._step, task._last_y_mm)
        try:
            obs, reward, terminated, truncated, info = super().step(action)
        except SensorSuspect as exc:
            if cell is None or before is None or counters is None:
                raise
            self._rezero_and_press_in(exc, before)
            assert isinstance(task, SurfaceTask)
            task._step, task._last_y_mm = counters  # the step is made again from its start
            obs, reward, terminated, truncated, info = super().step(action)
        info["sensor_rezeros"] = self.sensor_rezeros
        if (terminated or truncated) and self.task_spec.zero_check:
            info.update(self._check_zero())
        return obs, reward, terminated, truncated, info

    def _rezero_and_press_in(self, exc: SensorSuspect, where: Pose) -> None:
        """Retract, zero in free space, press in again to ``where`` (the step's start)."""
        assert self.session is not None and self.session.cell is not None
        cell, spec = self.session.cell, self.task_spec
        max_step = self.config.safety.max_step_mm
        log.warning("%s: retracting, zeroing in free space and pressing in again", exc)
        retract_and_retare(cell, spec.retract_y_mm, max_step)
        self.sensor_rezeros += 1
        above = Pose(where.x_mm, spec.retract_y_mm, where.z_mm, where.quaternion)
        cell.move_in_steps(above, max_step)
        cell.move_in_steps(where, max_step, guard_force=True)
        cell.reset_filter()

    def _check_zero(self) -> dict[str, Any]:
        """The episode's zero check (the tool retracted: free space); its info entries."""
        assert self.session is not None and self.session.cell is not None
        cell = self.session.cell
        force, bound = check_zero(cell)
        moved = abs(force) > bound
        if moved:  # the episode read through a moved zero: zero here for the next one
            log.warning("the zero check after the episode read %.2f N in free space (bound "
                        "%.2f N): the zero moved during the episode; zeroing here", force, bound)
            self.zero_voids += 1
            cell.zero_in_free_space()
        return {"zero_check_n": float(force), "zero_moved": bool(moved),
                "zero_voids": self.zero_voids}

    def _command(self, action: np.ndarray) -> np.ndarray:
        self._y_offset_mm = float(action[0]) * self.output_map.max_offset_mm
        return np.array([self._output.centre_at(self._x) + self._y_offset_mm])

    def _observation(self, x: np.ndarray, force_n: float) -> np.ndarray:
        obs = np.array([x[0], force_n, self._y_offset_mm], dtype=float)
        clipped: np.ndarray = np.clip(obs, self.observation_space.low, self.observation_space.high)
        return clipped

    def close_task(self) -> None:
        """Stop the robot, close the drivers and stop the emulators."""
        session, self.session = self.session, None
        if session is not None:
            try:
                if session.cell is not None:
                    session.cell.stop()
            finally:
                session.close()
        super().close_task()
