"""The physical cell shared by every emulator: where the tool is and what it touches.

One :class:`CellPhysics` object is handed to both the robot-controller emulator
and the JR3 emulator. The robot emulator writes the pose the robot *reached*
(:meth:`CellPhysics.set_pose`); the sensor emulator reads the true wrench that
pose produces (:meth:`CellPhysics.true_wrench`). Neither emulator knows the
other, and this module knows nothing of wires.

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
from typing import Protocol, runtime_checkable

import numpy as np

from forcelearn.devices import Pose, quaternion_to_matrix
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
    """

    def __init__(
        self,
        environment: ContactEnvironment | None = None,
        pose: Pose | None = None,
        tool: ToolParams | None = None,
    ):
        self._lock = threading.Lock()
        self.environment: ContactEnvironment = environment or NoContact()
        self._tool = tool or POINT_TOOL
        self._pose = pose or Pose(0.0, 0.0, 0.0)
        self._rotation, self._gravity = self._orientation_terms(self._pose)

    @property
    def tool(self) -> ToolParams:
        """The tool on the sensor (mass, centre of mass, contact point)."""
        return self._tool

    @tool.setter
    def tool(self, tool: ToolParams) -> None:
        with self._lock:
            self._tool = tool
            self._rotation, self._gravity = self._orientation_terms(self._pose)

    def _orientation_terms(self, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Rotation matrix and tool-weight wrench of a pose (cached: the sensor's hot path)."""
        rotation = quaternion_to_matrix(pose.quaternion)
        return rotation, gravity_wrench(self.tool, rotation)

    @property
    def pose(self) -> Pose:
        """The pose the robot has reached."""
        with self._lock:
            return self._pose

    def set_pose(self, pose: Pose) -> None:
        """Record the pose the robot has reached (called by the robot emulator)."""
        terms = self._orientation_terms(pose)
        with self._lock:
            self._pose = pose
            self._rotation, self._gravity = terms
            if isinstance(self.environment, PoseObserver):
                self.environment.observe_pose(pose.position_mm)

    def true_wrench(self) -> np.ndarray:
        """Return the noise-free wrench (6,) in the sensor frame, N and N·m.

        Contact force and moment about the sensor origin plus the tool's weight.
        """
        with self._lock:
            pose, rotation, gravity = self._pose, self._rotation, self._gravity
            force_world = self.environment.contact_force_world_n(pose.position_mm)
        if not force_world.any():
            return gravity.copy()
        return contact_wrench(self.tool, rotation, force_world) + gravity
