"""How the emulated arm's tool moves in time: planner, servo lag and in-position band.

A path planner with speed and acceleration limits, a servo that lags behind
it, and an in-position band.

Description
-----------
A command is taken by the controller at once (it becomes the *commanded
target*) but motion starts ``start_delay_s`` later, the time the controller
spends planning the path. The planner moves a reference point along the
straight segment from where the reference is to the target with a
trapezoidal speed profile: acceleration ``accel_mm_s2`` up to ``speed_mm_s``,
then braking so as to stop on the target. Orientation turns in step with the
position (normalised linear interpolation); a pure rotation takes
``angle / rotation_speed_deg_s``. The tool follows the reference through a
first-order servo lag of time constant ``lag_s``. The robot is *in position*
when the reference has stopped on the commanded target and the tool is within
``in_position_mm`` of it (and within 0.1 deg of its orientation).

A new command while moving starts a new segment from the present reference,
keeping the part of the speed that points the new way. STOP brakes along the
present segment at ``accel_mm_s2`` and makes the rest point the target.

Time advances on a fixed grid of ``tick_s`` (the controller's interpolation
period), so the motion does not depend on how often anyone looks at it.

Units: mm, s, degrees; poses in the robot base frame.

Defaults and where they come from
---------------------------------
=======================  ==========  ========================================================
parameter                default     source
=======================  ==========  ========================================================
speed_mm_s               100         assumption: a computer-link MoveL at v100, the
                                     speed data the paper's era used for contact work
accel_mm_s2              1000        assumption: about 0.1 g, a smooth TCP ramp for a
                                     large arm (IRB 2000 class) under a fine-point MoveL
start_delay_s            0.05        assumption: the S4 controller plans a received
                                     move before it starts (tens of ms)
lag_s                    0.03        assumption: position servo tracking lag of a
                                     1990s industrial arm (a few tens of ms)
in_position_mm           0.1         assumption: a "fine" stop point's band
rotation_speed_deg_s     60          assumption: reorientation speed of the tool
tick_s                   0.004       assumption: interpolation period (IRC5 and EGM
                                     run at 4 ms)
=======================  ==========  ========================================================

With these, a 5 mm step takes about 0.05 + 0.12 + 0.1 s (delay, travel, lag)
before the robot reports in position.
"""

from __future__ import annotations

import functools
import math
import struct
from collections import deque
from dataclasses import dataclass
from typing import Any, cast

from forcelearn.devices import Pose

Quaternion = tuple[float, float, float, float]
PoseKey = tuple[float, float, float, Quaternion]
"""A pose as (x, y, z, quaternion): compared without building a :class:`Pose`."""

_SNAP_MM = 1e-4
"""Below this distance the lagging tool is taken to have reached the reference."""
_ORIENTATION_BAND_DEG = 0.1


@dataclass(frozen=True)
class MotionParams:
    """Speed, acceleration, delay, lag and in-position band of the arm (mm, s, deg)."""

    speed_mm_s: float = 100.0
    accel_mm_s2: float = 1000.0
    start_delay_s: float = 0.05
    lag_s: float = 0.03
    in_position_mm: float = 0.1
    rotation_speed_deg_s: float = 60.0
    tick_s: float = 0.004
    instant: bool = False
    """Reach every target the instant it is commanded (the "ideal" profile)."""

    def __post_init__(self) -> None:
        for name in ("speed_mm_s", "accel_mm_s2", "rotation_speed_deg_s", "tick_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"arm {name} must be a positive number, got {value!r}")
        for name in ("start_delay_s", "lag_s", "in_position_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"arm {name} must be >= 0, got {value!r}")


def _nlerp(q0: tuple[float, ...], q1: tuple[float, ...], f: float) -> Quaternion:
    """Normalised linear interpolation of unit quaternions (the short way).

    Written out per component (the motion's hot path); the sums run in the
    order ``sum()`` would take them, so the result is the same to the bit.
    """
    if q0 == q1 and f >= 0.0:
        return _nlerp_to_itself(q0)
    return _nlerp_formula(q0, q1, f)


@functools.lru_cache(maxsize=16)
def _nlerp_to_itself(q: tuple[float, ...]) -> Quaternion:
    """:func:`_nlerp` of ``q`` towards itself, one object per orientation.

    The same for every ``f >= 0``: ``q + f * (q - q)`` is ``q`` (a -0.0 made +0.0) to
    the bit, then normalised as always; the arm's path asks it every tick it moves
    without turning.
    """
    return _nlerp_formula(q, q, 0.0)


def _nlerp_formula(q0: tuple[float, ...], q1: tuple[float, ...], f: float) -> Quaternion:
    """:func:`_nlerp` computed."""
    a0, a1, a2, a3 = q0
    b0, b1, b2, b3 = q1
    if a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 < 0:
        b0, b1, b2, b3 = -b0, -b1, -b2, -b3
    c0, c1 = a0 + f * (b0 - a0), a1 + f * (b1 - a1)
    c2, c3 = a2 + f * (b2 - a2), a3 + f * (b3 - a3)
    norm = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3)
    return (c0 / norm, c1 / norm, c2 / norm, c3 / norm)


def _angle_deg(q0: tuple[float, ...], q1: tuple[float, ...]) -> float:
    """Rotation angle between two unit quaternions, degrees.

    Written out per component (asked at every status poll); the sums run in the
    order ``sum()`` would take them, so the result is the same to the bit.
    """
    a0, a1, a2, a3 = q0
    b0, b1, b2, b3 = q1
    dot = abs(a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3)
    norm = (math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
            * math.sqrt(b0 * b0 + b1 * b1 + b2 * b2 + b3 * b3))
    return math.degrees(2.0 * math.acos(min(1.0, dot / norm)))


class ArmMotion:
    """The tool's motion in simulated time (pure: no clock, no threads; the caller advances it).

    Args:
        params: speed, acceleration, delay, lag and band.
        pose: where the tool is at power-up (at rest).
    """

    def __init__(self, params: MotionParams, pose: Pose) -> None:
        self.params = params
        self.speed_mm_s = params.speed_mm_s
        self._lag_keep = math.exp(-params.tick_s / params.lag_s) if params.lag_s > 0 else 0.0
        self._gain = 1.0 - self._lag_keep
        """The share of the way to the reference the lagging tool makes per tick."""
        self.tick_index = 0
        self.target = pose
        """The commanded target (what MOVE_BY adds to, what in-position compares with)."""
        self.stall_fraction: float | None = None
        """Fault: every segment stops at this fraction of its length (a robot that stops short)."""
        self._pending: deque[tuple[int, Pose]] = deque()
        self._unit_q: Quaternion | None = None
        self._unit_ref: Quaternion | None = None
        """An orientation (object) that :func:`_nlerp` towards this reference (object) returns
        unchanged to the bit: checked once, then not computed again while both stay."""
        self._pose_of: tuple[PoseKey | None, Pose] = (None, pose)
        """(:attr:`tool_key`, the :attr:`pose` built for it)."""
        self._segment_direction: tuple[list[float] | None, Pose | None, tuple[float, ...]] = (
            None, None, (0.0, 0.0, 0.0))
        """(segment start, goal, :meth:`_direction`) of the latest segment started: the next
        segment's old direction while that segment runs (its start and goal the same objects)."""
        self._turn: tuple[Any, Any, float] = (None, None, 0.0)
        """The latest (start orientation, goal orientation, :func:`_angle_deg`) of a segment."""
        self._terms: tuple[float, float, float, float, float, float, float,
                           Quaternion, Quaternion]
        """The present segment's length, start, goal and turns (:meth:`advance_keys` reads them)."""
        self._set_rest(pose)

    def _set_rest(self, pose: Pose) -> None:
        self._tool = [pose.x_mm, pose.y_mm, pose.z_mm]
        self._tool_q = cast(Quaternion, tuple(pose.quaternion))  # a Pose's four components
        self.tool_key: PoseKey = (pose.x_mm, pose.y_mm, pose.z_mm, self._tool_q)
        """Where the tool is, as (x, y, z, quaternion) without building a Pose (hot path: a
        plain attribute, set wherever the tool moves)."""
        self._ref = list(self._tool)
        self._ref_q = self._tool_q
        self._seg_start = list(self._tool)
        self._seg_start_q = self._tool_q
        self._seg_goal = pose
        self._seg_length = 0.0
        self._find_terms()
        self._seg_end = 0.0
        self._s = 0.0
        self._v = 0.0
        self._ref_s: float | None = None
        """The path point ``_ref`` was computed at on this segment (None: compute it again)."""

    # ---- what the controller sees ------------------------------------------------------
    @property
    def time_s(self) -> float:
        """The simulated time the motion has been advanced to, s."""
        return self.tick_index * self.params.tick_s

    @property
    def pose(self) -> Pose:
        """Where the tool is (mm, quaternion w x y z).

        One object while the tool stays (:attr:`tool_key` not set again): an arm at
        rest is asked every 4 ms EGM cycle, and its callers compare poses by
        identity before value.
        """
        key = self.tool_key
        known = self._pose_of
        if known[0] is key:
            return known[1]
        x, y, z = self._tool
        pose = Pose.of(x, y, z, self._tool_q)  # (the constructor's object, faster)
        self._pose_of = (key, pose)
        return pose

    @property
    def moving(self) -> bool:
        """True while a command is pending, the path runs, or the tool lags beyond the band."""
        if self._pending or self._s < self._seg_end or self._v > 0:
            return True
        return math.dist(self._tool, self._ref) > self.params.in_position_mm

    @property
    def in_position(self) -> bool:
        """True when at rest within the band of the commanded target."""
        if self._pending or self._s < self._seg_end or self._v > 0:
            return False
        t = self.target
        error = math.dist(self._tool, (t.x_mm, t.y_mm, t.z_mm))
        return (
            error <= self.params.in_position_mm
            and _angle_deg(self._tool_q, t.quaternion) <= _ORIENTATION_BAND_DEG
        )

    # ---- commands ----------------------------------------------------------------------
    def command(self, target: Pose, t_s: float) -> None:
        """Take a new target at simulated time ``t_s`` (motion starts after the delay)."""
        self.advance_to(t_s)
        self.target = target
        if self.params.instant:
            self._pending.clear()
            self._set_rest(target)
            return
        start_tick = math.ceil((t_s + self.params.start_delay_s) / self.params.tick_s - 1e-9)
        self._pending.append((max(start_tick, self.tick_index), target))

    def stop(self, t_s: float) -> None:
        """Brake to rest along the present segment; the rest point becomes the target."""
        self.advance_to(t_s)
        self._pending.clear()
        brake = self._v * self._v / (2.0 * self.params.accel_mm_s2)
        self._seg_end = min(self._seg_end, self._s + brake)
        self.target = self._point_at(self._seg_end)

    # ---- time --------------------------------------------------------------------------
    def tick_at(self, t_s: float) -> int:
        """The index of the last tick at or before ``t_s``."""
        return math.floor(t_s / self.params.tick_s + 1e-9)

    def advance_to(self, t_s: float, on_tick: Any = None) -> None:
        """Advance to the last tick at or before ``t_s``; ``on_tick(dt_s)`` after each tick.

        At rest with nothing pending the ticks are skipped in one jump and
        ``on_tick`` is called once with the whole span.
        """
        tick = self.params.tick_s
        last = self.tick_at(t_s)
        while self.tick_index < last:
            # at rest (no speed, the path done, the tool on the reference) with nothing pending
            if not self._pending and self._v == 0.0 and self._s >= self._seg_end and (
                self._tool == self._ref and self._tool_q == self._ref_q
            ):
                span = last - self.tick_index
                self.tick_index = last
                if on_tick is not None:
                    on_tick(span * tick)
                return
            self.tick_index += 1
            self._step(tick)
            if on_tick is not None:
                on_tick(tick)

    @property
    def resting(self) -> bool:
        """At rest with nothing pending (no speed, the path done, the tool on the reference).

        :meth:`advance_to` then jumps its ticks, and the tool stays until a command.
        """
        return not (self._pending or self._v != 0.0 or self._s < self._seg_end) and (
            self._tool == self._ref and self._tool_q == self._ref_q
        )

    def rest_span(self, t_s: float) -> int:
        """:meth:`advance_to` ``t_s`` if the arm is at rest with nothing pending: the ticks jumped.

        0: no tick to run; -1: the arm moves (nothing done, :meth:`advance_to` runs
        its ticks). The at-rest jump of :meth:`advance_to`, whose single ``on_tick``
        of ``span * tick_s`` the caller makes.
        """
        last = math.floor(t_s / self.params.tick_s + 1e-9)  # tick_at
        if self.tick_index >= last:
            return 0
        if self._pending or self._v != 0.0 or self._s < self._seg_end or not (
            self._tool == self._ref and self._tool_q == self._ref_q
        ):
            return -1
        span = last - self.tick_index
        self.tick_index = last
        return span

    def advance_keys(self, t_s: float) -> tuple[list[PoseKey], int]:
        """:meth:`advance_to` ``t_s`` without a callback, for a caller that takes the ticks at once.

        Returns the tool key (:attr:`tool_key`) after each tick stepped, in order, and the
        ticks jumped at rest at the end (0: none; :meth:`advance_to` would call
        ``on_tick`` once with that span). The same motion to the bit: :meth:`_step`'s
        operations in the same order, the call written out (the cell's hot path: about 200
        ticks per Surface-v0 step).
        """
        keys: list[PoseKey] = []
        tick = self.params.tick_s
        last = self.tick_at(t_s)
        pending = self._pending
        gain = self._gain
        accel = self.params.accel_mm_s2
        speed = self.speed_mm_s
        sqrt, dist = math.sqrt, math.dist
        # the state in locals, written back at the end and around a segment's start
        index, s, v, end = self.tick_index, self._s, self._v, self._seg_end
        ref, ref_q, ref_s = self._ref, self._ref_q, self._ref_s
        tool, tool_q = self._tool, self._tool_q
        unit_q, unit_ref = self._unit_q, self._unit_ref
        segment = self._terms
        rest = 0
        while index < last:
            if not pending and v == 0.0 and s >= end and tool == ref and tool_q == ref_q:
                rest, index = last - index, last
                break
            index += 1
            # _step(tick), written out
            if pending and pending[0][0] <= index:
                self.tick_index, self._s, self._v, self._ref_s = index, s, v, ref_s
                self._ref, self._ref_q = ref, ref_q  # what a new segment starts from
                while pending and pending[0][0] <= index:
                    self._start_segment(pending.popleft()[1])
                s, v, end, ref_s = self._s, self._v, self._seg_end, self._ref_s
                segment = self._terms
            if s < end:  # min(...) of three, then of two, written as comparisons
                v = v + accel * tick
                if speed < v:
                    v = speed
                brake = sqrt(2.0 * accel * (end - s))
                if brake < v:
                    v = brake
                ahead = s + v * tick
                s = ahead if ahead < end else end
                if s >= end:
                    v = 0.0
            else:
                v = 0.0
            if s != ref_s:  # the reference stands still while the tool catches up
                # _reference_at(s), written out
                length, x0, y0, z0, gx, gy, gz, q0, gq = segment
                f = 1.0 if length == 0.0 else s / length
                ref = [x0 + f * (gx - x0), y0 + f * (gy - y0), z0 + f * (gz - z0)]
                ref_q = gq if f >= 1.0 else _nlerp(q0, gq, f)
                ref_s = s
            (tx, ty, tz), (rx, ry, rz) = tool, ref
            tool = [tx + gain * (rx - tx), ty + gain * (ry - ty), tz + gain * (rz - tz)]
            if s >= end and dist(tool, ref) < _SNAP_MM:
                tool, tool_q = list(ref), ref_q
            elif tool_q is not unit_q or ref_q is not unit_ref:
                turned = _nlerp(tool_q, ref_q, gain)
                if turned == tool_q and (struct.pack("<4d", *turned)
                                         == struct.pack("<4d", *tool_q)):
                    unit_q, unit_ref, turned = tool_q, ref_q, tool_q
                tool_q = turned
            keys.append((tool[0], tool[1], tool[2], tool_q))
        self.tick_index, self._s, self._v, self._ref_s = index, s, v, ref_s
        self._ref, self._ref_q, self._tool, self._tool_q = ref, ref_q, tool, tool_q
        self._unit_q, self._unit_ref = unit_q, unit_ref
        if keys:
            self.tool_key = keys[-1]
        return keys, rest

    def _find_terms(self) -> None:
        """Keep what :meth:`_reference_at` reads of the segment just set (:attr:`_terms`)."""
        goal = self._seg_goal
        x0, y0, z0 = self._seg_start
        self._terms = (self._seg_length, x0, y0, z0, goal.x_mm, goal.y_mm, goal.z_mm,
                       self._seg_start_q, goal.quaternion)

    def _step(self, dt: float) -> None:
        pending = self._pending
        while pending and pending[0][0] <= self.tick_index:
            self._start_segment(pending.popleft()[1])
        s, end = self._s, self._seg_end
        if s < end:
            accel = self.params.accel_mm_s2
            v = min(self._v + accel * dt, self.speed_mm_s, math.sqrt(2.0 * accel * (end - s)))
            self._s = s = min(end, s + v * dt)
            self._v = 0.0 if s >= end else v
        else:
            self._v = 0.0
        if s != self._ref_s:  # the reference stands still while the tool catches up
            self._ref, self._ref_q = self._reference_at(s)
            self._ref_s = s
        gain = self._gain
        ref = self._ref
        (tx, ty, tz), (rx, ry, rz) = self._tool, ref
        tool = [tx + gain * (rx - tx), ty + gain * (ry - ty), tz + gain * (rz - tz)]
        if s >= end and math.dist(tool, ref) < _SNAP_MM:
            tool, self._tool_q = list(ref), self._ref_q
        elif self._tool_q is not self._unit_q or self._ref_q is not self._unit_ref:
            q = self._tool_q
            turned = _nlerp(q, self._ref_q, gain)
            if turned == q and struct.pack("<4d", *turned) == struct.pack("<4d", *q):
                # this reference leaves this orientation as it is, to the bit: skip it from now on
                self._unit_q, self._unit_ref, turned = q, self._ref_q, q
            self._tool_q = turned
        self._tool = tool
        self.tool_key = (tool[0], tool[1], tool[2], self._tool_q)

    def _start_segment(self, goal: Pose) -> None:
        """A new segment from the present reference to ``goal``, keeping the speed along it.

        Written out (a ramp starts one every 4 ms cycle): the operations of
        :meth:`_direction` and of the speed carry-over's ``sum`` in the same order
        (``sum`` adds from 0.0: the same floats but a zero's sign, which only
        ``carry > 0`` reads).
        """
        start, start_q = list(self._ref), self._ref_q
        known = self._segment_direction  # the present segment's, if found at its start
        if known[0] is self._seg_start and known[1] is self._seg_goal:
            old_dir = known[2]
        else:
            old_dir = self._direction()
        gx, gy, gz, goal_q = goal.x_mm, goal.y_mm, goal.z_mm, goal.quaternion
        distance = math.dist(start, (gx, gy, gz))
        turned = self._turn
        if start_q == turned[0] and goal_q == turned[1]:  # (equal values: the same angle)
            turn = turned[2]
        else:
            turn = _angle_deg(start_q, goal_q)
            self._turn = (start_q, goal_q, turn)
        length = max(distance, turn * self.speed_mm_s / self.params.rotation_speed_deg_s)
        self._seg_start, self._seg_start_q, self._seg_goal = start, start_q, goal
        self._seg_length = length
        self._terms = (length, start[0], start[1], start[2], gx, gy, gz, start_q, goal_q)
        self._ref_s = None
        self._s = 0.0
        self._seg_end = length if self.stall_fraction is None else length * self.stall_fraction
        dx, dy, dz = gx - start[0], gy - start[1], gz - start[2]  # _direction(), written out
        norm = math.sqrt(dx * dx + dy * dy + dz * dz)
        new_dir = (0.0, 0.0, 0.0) if norm == 0.0 else (dx / norm, dy / norm, dz / norm)
        self._segment_direction = (start, goal, new_dir)
        carry = old_dir[0] * new_dir[0] + old_dir[1] * new_dir[1] + old_dir[2] * new_dir[2]
        self._v = self._v * carry if carry > 0 else 0.0

    def _direction(self) -> tuple[float, float, float]:
        goal = self._seg_goal
        delta = [g - s for g, s in zip((goal.x_mm, goal.y_mm, goal.z_mm), self._seg_start,
                                       strict=True)]
        norm = math.sqrt(sum(c * c for c in delta))
        if norm == 0.0:
            return (0.0, 0.0, 0.0)
        return (delta[0] / norm, delta[1] / norm, delta[2] / norm)

    def _point_at(self, s: float) -> Pose:
        (x, y, z), q = self._reference_at(s)
        return Pose(x, y, z, q)

    def _reference_at(self, s: float) -> tuple[list[float], Quaternion]:
        """The path's point ``s`` mm along the segment: [x, y, z] and quaternion."""
        f = 1.0 if self._seg_length == 0.0 else s / self._seg_length
        goal = self._seg_goal
        x0, y0, z0 = self._seg_start
        xyz = [x0 + f * (goal.x_mm - x0), y0 + f * (goal.y_mm - y0), z0 + f * (goal.z_mm - z0)]
        q = goal.quaternion if f >= 1.0 else _nlerp(self._seg_start_q, goal.quaternion, f)
        return xyz, q

    # ---- checkpoint --------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """Everything a bit-identical resume needs (JSON-able)."""
        def pose(p: Pose) -> list[float]:
            return [p.x_mm, p.y_mm, p.z_mm, *p.quaternion]

        return {
            "tick_index": self.tick_index,
            "speed_mm_s": self.speed_mm_s,
            "target": pose(self.target),
            "pending": [[tick, pose(p)] for tick, p in self._pending],
            "tool": [*self._tool, *self._tool_q],
            "ref": [*self._ref, *self._ref_q],
            "seg_start": [*self._seg_start, *self._seg_start_q],
            "seg_goal": pose(self._seg_goal),
            "seg": [self._seg_length, self._seg_end, self._s, self._v],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        def pose(v: list[float]) -> Pose:
            return Pose(v[0], v[1], v[2], tuple(v[3:7]))  # type: ignore[arg-type]

        self.tick_index = int(state["tick_index"])
        self.speed_mm_s = float(state["speed_mm_s"])
        self.target = pose(state["target"])
        self._pending = deque((int(t), pose(p)) for t, p in state["pending"])
        tool, ref, start = state["tool"], state["ref"], state["seg_start"]
        self._tool, self._tool_q = list(tool[:3]), tuple(tool[3:7])
        self.tool_key = (self._tool[0], self._tool[1], self._tool[2], self._tool_q)
        self._ref, self._ref_q = list(ref[:3]), tuple(ref[3:7])
        self._seg_start, self._seg_start_q = list(start[:3]), tuple(start[3:7])
        self._seg_goal = pose(state["seg_goal"])
        self._seg_length, self._seg_end, self._s, self._v = (float(x) for x in state["seg"])
        self._find_terms()
        self._ref_s = None
