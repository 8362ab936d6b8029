"""The physical cell shared by every emulator: where the tool is and what it touches.

One :class:`CellPhysics` object is handed to both the robot-controller emulator
and the JR3 emulator, with the cell's one :class:`~forcelearn.emulators.clock.SimClock`.
The robot emulator commands the arm's :class:`~.arm_motion.ArmMotion`
(:attr:`CellPhysics.motion`); whoever needs the present state first calls
:meth:`CellPhysics.advance_to` with the simulated time, which moves the arm
and lets the environment (the sponge's relaxation) evolve on the motion's
tick grid. The sensor emulator then reads the true wrench
(:meth:`CellPhysics.true_wrench`). Without a motion model (tests, tools) a
pose can be written directly with :meth:`CellPhysics.set_pose`. Neither
emulator knows the other, and this module knows nothing of wires.

Frames and units
----------------
* World frame: robot base, z up, gravity (0, 0, -9.81) m/s². Positions in mm.
* Tool pose: the tool centre point (the roller's contact point), orientation a
  unit quaternion (w, x, y, z) mapping sensor frame to world frame.
* Wrench: (Fx, Fy, Fz, Mx, My, Mz) in N and N·m, expressed in the sensor frame,
  the external load acting on the sensor (contact reaction + tool weight).
  Moments are taken about the sensor origin: the contact force acts at the
  tool's contact point, the weight at its centre of mass (see :mod:`.tool`).
* The paper's task: the tool presses the sponge along Y (see :mod:`.sponge`).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any, Protocol, cast, runtime_checkable

import numpy as np

from forcelearn.devices import Pose, quaternion_to_matrix
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.physics.arm_motion import ArmMotion, PoseKey, Quaternion
from forcelearn.emulators.physics.tick_runs import ticks_by_length
from forcelearn.emulators.physics.tool import POINT_TOOL, ToolParams, contact_wrench, gravity_wrench


class ContactEnvironment(Protocol):
    """A surface the tool can press on."""

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        """Return the reaction force (3,) in N, world frame, on a tool at ``position_mm``."""
        ...


@runtime_checkable
class PoseObserver(Protocol):
    """An environment that changes with where the tool has been (e.g. counts passes)."""

    def observe_pose(self, position_mm: np.ndarray) -> None:
        """Note the tool position (mm) the robot has reached."""
        ...


@runtime_checkable
class TimedEnvironment(Protocol):
    """An environment with a state that changes in time (e.g. a relaxing sponge)."""

    def evolve(self, position_mm: np.ndarray, dt_s: float) -> None:
        """Advance ``dt_s`` seconds during which the tool moved to ``position_mm``."""
        ...


@runtime_checkable
class TickedEnvironment(Protocol):
    """A timed pose observer that takes one motion tick in one call (the hot path)."""

    def tick(self, position_mm: tuple[float, float, float], dt_s: float, moved: bool) -> None:
        """``observe_pose(position_mm)`` if the tool ``moved``, then ``evolve(...)``."""
        ...


@runtime_checkable
class BatchTickedEnvironment(Protocol):
    """A ticked environment that takes a run of motion ticks in one call."""

    def ticks(self, keys: Sequence[PoseKey], dt_s: float, before: PoseKey) -> PoseKey:
        """``tick`` for each tool key, ``dt_s`` each; returns the last key recorded.

        A key is a tick the tool moved on when it differs from the last one recorded
        (at first ``before``).
        """
        ...


@runtime_checkable
class OrientedEnvironment(Protocol):
    """An environment whose contact depends on the tool's orientation (a part, a tilted tool)."""

    def observe_orientation(self, quaternion: Quaternion) -> None:
        """Note the tool's orientation (w, x, y, z), before the pose is reported at it."""
        ...


class NoContact:
    """Free space: never any contact force."""

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        """Return zero force, whatever the position."""
        return np.zeros(3)


class CellPhysics:
    """Pose of the tool plus the environment it presses on; thread-safe.

    Args:
        environment: the contact environment (default: free space). If it is a
            :class:`PoseObserver`, every reached pose is reported to it.
        pose: the initial tool pose.
        tool: the tool's mass and geometry (default: a massless point tool, so
            the wrench is the contact force alone).
        clock: the cell's simulated clock (default: a new one).
    """

    def __init__(
        self,
        environment: ContactEnvironment | None = None,
        pose: Pose | None = None,
        tool: ToolParams | None = None,
        clock: SimClock | None = None,
    ):
        self._lock = threading.RLock()
        self.environment = environment or NoContact()
        self.clock = clock or SimClock()
        self.motion: ArmMotion | None = None
        self._tool = tool or POINT_TOOL
        first = pose or Pose(0.0, 0.0, 0.0)
        self._pose: Pose | None = first
        """The tool's pose (None: moved by a motion tick since last read; see :attr:`pose`)."""
        self._pose_key: PoseKey = (first.x_mm, first.y_mm, first.z_mm, first.quaternion)
        """Where the tool is as (x, y, z, quaternion): what the hot path compares."""
        if self._oriented is not None:
            self._oriented.observe_orientation(first.quaternion)
        self._position: tuple[float, float, float] = (first.x_mm, first.y_mm, first.z_mm)
        """Where the tool is, mm (floats; the array :attr:`_position_mm` is built when asked)."""
        self._position_array: np.ndarray | None = first.position_mm
        self._rotation, self._gravity = self._orientation_terms(first.quaternion)
        self._wrench_key: tuple[float, ...] | None = None
        """The contact force the cached wrench was computed for (None: recompute)."""
        self._wrench = np.zeros(6)
        self._wrench_values: tuple[float, ...] = (0.0,) * 6
        """``_wrench`` as floats (:meth:`true_wrench_values`)."""

    def _move_tool(self, key: PoseKey) -> None:
        """Record the tool at (x, y, z, quaternion); the Pose is built when :attr:`pose` is read."""
        self._record_tool(key)
        if self._observer is not None:
            point: Any = self._position if self._tuples else self._position_mm  # as _point()
            self._observer.observe_pose(point)

    def _record_tool(self, key: PoseKey) -> None:
        """:meth:`_move_tool` without reporting the pose to the environment."""
        if key[3] != self._pose_key[3]:
            self._rotation, self._gravity = self._orientation_terms(key[3])
            if self._oriented is not None:
                self._oriented.observe_orientation(key[3])
        self._pose = None  # a motion tick moves the tool far more often than anyone reads it
        self._pose_key = key
        self._position = (key[0], key[1], key[2])
        self._position_array = None

    @property
    def _position_mm(self) -> np.ndarray:
        """Where the tool is, mm, as an array (built once per position)."""
        if self._position_array is None:
            self._position_array = np.array(self._position, dtype=float)
        return self._position_array

    def _point(self) -> Any:
        """The position as the environment takes it: a tuple if it accepts one, else the array."""
        return self._position if self._tuples else self._position_mm

    @property
    def environment(self) -> ContactEnvironment:
        """What the tool presses on."""
        return self._environment

    @environment.setter
    def environment(self, environment: ContactEnvironment) -> None:
        # Protocol checks are slow (typing inspects the class); the hot path asks once.
        self._environment = environment
        self._timed = environment if isinstance(environment, TimedEnvironment) else None
        self._observer = environment if isinstance(environment, PoseObserver) else None
        self._oriented = environment if isinstance(environment, OrientedEnvironment) else None
        self._tuples = bool(getattr(environment, "accepts_point_tuple", False))
        self._ticked = (environment if self._tuples and isinstance(environment, TickedEnvironment)
                        and self._timed is not None and self._observer is not None else None)
        self._batched = (environment if self._ticked is not None and self._oriented is None
                         and isinstance(environment, BatchTickedEnvironment) else None)
        if self._oriented is not None and hasattr(self, "_pose_key"):
            self._oriented.observe_orientation(self._pose_key[3])

    def attach_motion(self, motion: ArmMotion) -> None:
        """Let ``motion`` move the tool from now on (its pose is published at once)."""
        with self._lock:
            self.motion = motion
            self._move_tool(motion.tool_key)

    def advance_to(self, t_s: float | None = None) -> None:
        """Bring the arm and the environment to simulated time ``t_s`` (default: the clock's now).

        Never goes back: a time before the present state is ignored.
        """
        t = self.clock.now_s if t_s is None else t_s
        with self._lock:
            motion = self.motion
            if motion is None:
                return
            if motion.tick_index >= motion.tick_at(t) and motion.tool_key == self._pose_key:
                return  # no tick to run (the sensor's samples are closer than a tick)
            timed = self._timed
            tuples = self._tuples
            ticked = self._ticked
            batched = self._batched
            if batched is not None and ticked is not None and "_move_tool" not in self.__dict__:
                # the ticks as on_tick_ticked below takes them, the arm's first, then the
                # environment's in one call (the arm does not depend on it; nothing here is
                # oriented, so the orientation terms are needed at the last key only)
                keys, rest = motion.advance_keys(t)
                recorded = self._pose_key
                if keys:
                    recorded = batched.ticks(keys, motion.params.tick_s, recorded)
                if rest:
                    recorded = batched.ticks((motion.tool_key,), rest * motion.params.tick_s,
                                             recorded)
                if recorded is not self._pose_key:
                    self._record_tool(recorded)
                key = motion.tool_key
                if key != self._pose_key:  # an instant arm moves between ticks
                    self._move_tool(key)
                return
            if ticked is not None and "_move_tool" not in self.__dict__:
                # what on_tick below does, in one call to the environment (a hook that wraps
                # this object's _move_tool to see every tick takes the route below)
                def on_tick_ticked(dt_s: float) -> None:
                    key = motion.tool_key
                    if key != self._pose_key:
                        self._record_tool(key)
                        ticked.tick(self._position, dt_s, True)
                    else:
                        ticked.tick(self._position, dt_s, False)

                motion.advance_to(t, on_tick_ticked)
                key = motion.tool_key
                if key != self._pose_key:  # an instant arm moves between ticks
                    self._move_tool(key)
                return

            def on_tick(dt_s: float) -> None:
                key = motion.tool_key
                if key != self._pose_key:
                    self._move_tool(key)
                if timed is not None:
                    point: Any = self._position if tuples else self._position_mm  # as _point()
                    timed.evolve(point, dt_s)

            motion.advance_to(t, on_tick)
            key = motion.tool_key
            if key != self._pose_key:  # an instant arm moves between ticks
                self._move_tool(key)

    def rest_to(self, t_s: float) -> bool:
        """:meth:`advance_to` ``t_s`` if the arm stays at rest there; False: it moves, nothing done.

        The at-rest jump of the fused tick route (:meth:`ArmMotion.rest_span`, then the
        environment's one tick over the span, the tool not moved) without building
        the route's tick callback: what an EGM cycle at rest runs every 4 ms. False
        also where :meth:`advance_to` takes another route (no ticked environment, a
        hooked ``_move_tool``, the tool not where the arm is).
        """
        with self._lock:
            motion, ticked = self.motion, self._ticked
            if (motion is None or ticked is None or "_move_tool" in self.__dict__
                    or motion.tool_key != self._pose_key):
                return False
            span = motion.rest_span(t_s)
            if span < 0:
                return False
            if span:
                ticked.tick(self._position, span * motion.params.tick_s, False)
            return True

    def at_rest(self) -> bool:
        """Whether :meth:`rest_to` does every advance from now until the arm is commanded."""
        with self._lock:
            motion = self.motion
            return (motion is not None and self._ticked is not None
                    and "_move_tool" not in self.__dict__ and motion.tool_key == self._pose_key
                    and motion.resting)

    def rest_through(self, times_s: Sequence[float]) -> None:
        """:meth:`rest_to` each of ``times_s`` in turn (:meth:`at_rest` must hold), one lock.

        Raises ``RuntimeError`` (nothing done) if the arm is not at rest.
        """
        with self._lock:
            if not self.at_rest():
                raise RuntimeError("rest_through needs the arm at rest (at_rest())")
            motion, ticked, batched = self.motion, self._ticked, self._batched
            assert motion is not None and ticked is not None
            rest_span, tick, position = motion.rest_span, motion.params.tick_s, self._position
            if batched is None:
                for t_s in times_s:
                    span = rest_span(t_s)  # >= 0: at rest it stays (only the tick index moves)
                    if span:
                        ticked.tick(position, span * tick, False)
                return
            # the same ticks as runs of one span each through ``ticks``: a key equal to the one
            # recorded evolves at the recorded position, the tool not moved (as ``tick`` above)
            key = self._pose_key
            ticks_by_length(batched, (((key,), span * tick) for t_s in times_s
                                      if (span := rest_span(t_s))), key)

    def can_run(self) -> bool:
        """Whether :meth:`take_run` may take the arm's ticks from now (the fused tick route).

        So when the environment is a batched foam with ``ticks_seen``, no hook wraps
        ``_move_tool``, the tool is where the arm is and the pose read is the one set.
        """
        with self._lock:
            motion = self.motion
            return (motion is not None and not motion.params.instant and self._batched is not None
                    and hasattr(self._batched, "ticks_seen")
                    and "_move_tool" not in self.__dict__ and motion.tool_key == self._pose_key
                    and self._pose is not None)

    def take_run(self, cycles: Sequence[tuple[list[PoseKey], int, PoseKey, Pose | None]]) -> None:
        """The environment's side of cycles whose arm ticks ran already (:meth:`can_run` held).

        Each cycle is (the tool keys of its ticks, the ticks jumped at rest after them, the
        tool key then, the pose :meth:`set_pose` was given after it or None), as
        :meth:`ArmMotion.advance_keys` gave them: the same state as :meth:`advance_to`
        then :meth:`set_pose` cycle by cycle, the environment's ticks taken at once
        (``ticks_seen``).
        """
        with self._lock:
            motion, batched = self.motion, self._batched
            assert motion is not None and batched is not None
            tick = motion.params.tick_s
            runs: list[tuple[Sequence[PoseKey], float, tuple[float, float, float] | None]] = []
            last = None
            for keys, rest, key, pose in cycles:
                if keys:
                    runs.append((keys, tick, None))
                if rest:
                    runs.append(((key,), rest * tick, None))
                if pose is not None:
                    last = pose
                    seen = (pose.x_mm, pose.y_mm, pose.z_mm)
                    if runs and runs[-1][2] is None:
                        runs[-1] = (runs[-1][0], runs[-1][1], seen)
                    else:
                        runs.append(((), tick, seen))
            recorded = cast(Any, batched).ticks_seen(runs, self._pose_key)
            if recorded is not self._pose_key:
                self._record_tool(recorded)
            if last is not None:  # set_pose without its observation (ticks_seen made it)
                self._record_tool((last.x_mm, last.y_mm, last.z_mm, last.quaternion))
                self._pose = last

    @property
    def tool(self) -> ToolParams:
        """The tool on the sensor (mass, centre of mass, contact point)."""
        return self._tool

    @tool.setter
    def tool(self, tool: ToolParams) -> None:
        with self._lock:
            self._tool = tool
            self._rotation, self._gravity = self._orientation_terms(self._pose_key[3])

    def _orientation_terms(self, quaternion: Quaternion) -> tuple[np.ndarray, np.ndarray]:
        """Rotation matrix and tool-weight wrench of an orientation (cached: a hot path)."""
        self._wrench_key = None  # the cached wrench was of the old orientation or tool
        rotation = quaternion_to_matrix(quaternion)
        return rotation, gravity_wrench(self.tool, rotation)

    @property
    def pose(self) -> Pose:
        """The pose the robot has reached."""
        with self._lock:
            if self._pose is None:
                x, y, z, quaternion = self._pose_key
                self._pose = Pose(x, y, z, quaternion)
            return self._pose

    def holds(self, pose: Pose) -> bool:
        """Whether :attr:`pose` is ``pose`` (the object), without building the pose if moved."""
        return self._pose is pose

    def set_pose(self, pose: Pose) -> None:
        """Record the pose the tool has reached (by the motion model, or directly in tests)."""
        with self._lock:
            self._move_tool((pose.x_mm, pose.y_mm, pose.z_mm, pose.quaternion))
            self._pose = pose

    def true_wrench(self) -> np.ndarray:
        """Return the noise-free wrench (6,) in the sensor frame, N and N·m.

        Contact force and moment about the sensor origin plus the tool's weight.
        """
        with self._lock:
            force_world = self.environment.contact_force_world_n(self._point())
            self._wrench_at(tuple(force_world.tolist()))
            return self._wrench.copy()

    def true_wrench_values(self) -> tuple[float, ...]:
        """:meth:`true_wrench` as six floats (its ``tolist``): what a sensor model reads.

        The same wrench without an array copied per sample (the environment's force
        taken as floats where it gives them, ``contact_force_world_values``); a
        ``true_wrench`` wrapped on the object (fault_inject) or overridden is asked itself.
        """
        if "true_wrench" in self.__dict__ or type(self).true_wrench is not CellPhysics.true_wrench:
            return tuple(self.true_wrench().tolist())  # a wrapped or overridden wrench is asked
        with self._lock:
            values = getattr(self._environment, "contact_force_world_values", None)
            if values is None:
                key = tuple(self._environment.contact_force_world_n(self._point()).tolist())
            else:
                key = values(self._point())
            self._wrench_at(key)
            return self._wrench_values

    def _wrench_at(self, force_world: tuple[float, ...]) -> None:
        """Bring the cached wrench to the contact force ``force_world`` (N, world frame)."""
        # The force changes once per motion tick, the sensor samples many times per tick.
        if force_world != self._wrench_key:
            self._wrench_key = force_world
            if any(force_world):
                self._wrench = (contact_wrench(self._tool, self._rotation, np.array(force_world))
                                + self._gravity)
            else:
                self._wrench = self._gravity.copy()
            self._wrench_values = tuple(self._wrench.tolist())
