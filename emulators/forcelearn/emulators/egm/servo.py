"""Motion model behind the emulated EGM controller: dead time plus a first-order lag (pure).

Position guidance on a real controller acts with a control lag: ABB's manual
(3HAC073318 RW7, p.17) gives 10-20 ms "depending on the robot type" and "usually
around 20 ms" from writing a position until it starts to affect the robot;
users measure 40-50 ms end to end (abb_libegm issue #49). The model:

=================  ==========  ==============================================
parameter          default     meaning
=================  ==========  ==============================================
``control_lag_s``  0.020 s     dead time from the controller reading a planned
                               pose to the servo starting toward it (manual)
``time_constant_s`` 0.010 s    first-order lag of the axis servo after the
                               dead time (assumption), so a step is 95 %
                               reached 20 + 30 = 50 ms after it is read
=================  ==========  ==============================================

Orientation follows by normalised linear interpolation with the same fraction.

Seam: the emulator needs only ``command(target, t_s)`` and ``advance_to(t_s) -> Pose``
(:class:`MotionModel`); the shared ``CellPhysics.motion`` model, when it lands,
can replace :class:`LagServo` through ``EgmControllerEmulator(motion=...)``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from forcelearn.devices import Pose, blend_poses, multiply_quaternions


class MotionModel(Protocol):
    """What the EGM emulator asks of the arm's motion model (times in simulated seconds)."""

    def command(self, target: Pose, t_s: float) -> None:
        """A new planned pose, read by the controller at ``t_s``."""
        ...

    def advance_to(self, t_s: float) -> Pose:
        """Move the arm to ``t_s``; return the pose reached."""
        ...


@dataclass(frozen=True)
class ServoParams:
    """Dead time and lag of the emulated EGM position servo (s)."""

    control_lag_s: float = 0.020
    """ABB manual 3HAC073318 p.17: "usually around 20 ms"."""
    time_constant_s: float = 0.010
    """First-order lag after the dead time (assumption); 0 = reach at once."""

    def __post_init__(self) -> None:
        for name in ("control_lag_s", "time_constant_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"servo.{name} must be >= 0 s, got {value!r}")


class LagServo:
    """Dead time + first-order lag toward the latest planned pose. Not thread-safe."""

    def __init__(self, params: ServoParams, pose: Pose, t_s: float = 0.0) -> None:
        self.params = params
        self.pose = pose
        self.target = pose
        """The planned pose now acting on the servo (after the dead time)."""
        self._time_s = t_s
        self._queue: deque[tuple[float, Pose]] = deque()

    def command(self, target: Pose, t_s: float) -> None:
        """Plan ``target``; it starts to act at ``t_s + control_lag_s``."""
        self._queue.append((t_s + self.params.control_lag_s, target))

    def hold(self, t_s: float) -> None:
        """Stop at once where the arm is at ``t_s`` (drop every planned pose)."""
        self.advance_to(t_s)
        self._queue.clear()
        self.target = self.pose

    def advance_to(self, t_s: float) -> Pose:
        """Integrate exactly up to ``t_s`` (never back); return the pose."""
        while self._queue and self._queue[0][0] <= t_s:
            due, target = self._queue.popleft()
            self._relax(due)
            self.target = target
        self._relax(t_s)
        return self.pose

    def _relax(self, t_s: float) -> None:
        dt = t_s - self._time_s
        if dt <= 0:
            return
        self._time_s = t_s
        if self.pose == self.target:
            return
        tau = self.params.time_constant_s
        fraction = 1.0 if tau == 0 else 1.0 - math.exp(-dt / tau)
        self.pose = blend_poses(self.pose, self.target, fraction)



def feed_forward_pose(target: Pose, speed_ref: tuple[float, ...] | None, tau_s: float) -> Pose:
    """``target`` led by speedRef x ``tau_s``: the lag's fixed point under the speed feed-forward.

    speedRef is six numbers (mm/s, then deg/s about the base axes); without six
    finite ones ``target`` is returned as it is.
    """
    if speed_ref is None or len(speed_ref) != 6 or not all(math.isfinite(v) for v in speed_ref):
        return target
    x, y, z = (float(c) for c in target.position_mm + np.asarray(speed_ref[:3]) * tau_s)
    turn = np.radians(np.asarray(speed_ref[3:])) * tau_s  # rotation vector, base frame
    angle = float(np.linalg.norm(turn))
    quaternion = target.quaternion
    if angle > 0.0:
        axis = turn / angle
        w, s = math.cos(angle / 2.0), math.sin(angle / 2.0)
        turn_q = (w, *(float(c) * s for c in axis))
        quaternion = multiply_quaternions(turn_q, target.quaternion)
    return Pose(x, y, z, quaternion)
