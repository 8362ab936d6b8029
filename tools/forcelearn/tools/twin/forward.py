"""The twin's forward model: the emulated sponge and arm, vectorised over a run's trials.

Force
-----
The emulated sponge's own law, :mod:`forcelearn.emulators.physics.sponge_law`,
called over arrays with the typed :class:`SpongeParams` (one code: a test
checks the two agree to 1e-12 on every member of the foam family): surface
``surface_y(z, n)`` and stiffness ``k(z, n)`` after ``n`` passes, a standard
linear solid's relaxing part ``q``, hysteresis and friction, the rigid backing
beyond the foam. What is the forward model's own is the state at each burst,
from the recorded moves. The depth follows the tool from one reached pose to the
next along the emulated arm's own path in time, ending at the (true) in-position
time: the tool's Y and Z go along a straight line, the depth is the surface's
under the tool at each point (a short waviness bends it within a move), linear
within each of ``PATH_POINTS`` slices, for which ``q`` is exact;
``q`` then decays until the burst, and the burst reads its mean over the
burst's span. The tool's remaining lag error at the burst decays from the
reached pose toward the command with the servo lag. The reading is the
force's component along the run's ``[filter]`` axis and sign, in the sensor
frame of the task's tool orientation.

Hysteresis and friction (:func:`contact_state`) follow the tool's path, as the
emulated sponge updates them at every reported pose: the Dahl state through
``hysteresis_step``'s closed form on each piece of a sampled path per move,
the friction along the last piece that slid along the surface. With
``hysteresis_loss = friction_coefficient = 0`` neither is computed and the
model is the one without them, operation for operation.

Arm
---
The time from a command to in position and the tool's path over each move: the
emulated arm's own motion on its tick grid (start delay, trapezoidal reference,
first-order servo lag, in-position band), :mod:`forcelearn.tools.twin.arm_model`.

Units: mm, s, N, passes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from forcelearn.devices import quaternion_to_matrix
from forcelearn.emulators.physics import sponge_law as law
from forcelearn.emulators.physics.sponge_law import SpongeParams
from forcelearn.tools.twin import arm_model
from forcelearn.tools.twin.arrays import RecordArrays


@dataclass(frozen=True)
class Reading:
    """How a contact force in the world frame becomes the recorded normal force."""

    along_y: float
    """Reading per newton of world +Y force."""
    along_z: float
    """Reading per newton of world +Z force."""

    @classmethod
    def of(cls, orientation: tuple[float, float, float, float], axis: int,
           sign: float) -> Reading:
        """The reading of a tool with ``orientation`` (w, x, y, z), filter ``axis``, ``sign``."""
        rotation = quaternion_to_matrix(orientation)  # sensor -> world
        return cls(sign * float(rotation[1, axis]), sign * float(rotation[2, axis]))


def recorded_force_n(p: SpongeParams, passes: np.ndarray, y_mm: np.ndarray,
                     z_mm: np.ndarray, relaxing_mm: np.ndarray | float,
                     reading: Reading, contact: ContactState | None = None) -> np.ndarray:
    """The recorded normal force (N) of tool points with relaxing part ``relaxing_mm``.

    The sponge's :func:`~forcelearn.emulators.physics.sponge_law.contact_force_n` at
    the points, read along the run's axis. ``contact`` (:func:`contact_state`) gives the
    hysteresis state and the last slide; None: neither (s = 0, no slide).
    """
    points = np.stack([np.zeros_like(y_mm), y_mm, z_mm], axis=-1)
    hysteresis: np.ndarray | float = 0.0
    slide: np.ndarray = np.zeros(3)
    if contact is not None:
        hysteresis = contact.hysteresis
        slide = np.stack([np.zeros_like(contact.slide_y), contact.slide_y, contact.slide_z],
                         axis=-1)
    force = law.contact_force_n(p, passes, points, relaxing_mm, hysteresis, slide)
    result: np.ndarray = force[..., 1] * reading.along_y + force[..., 2] * reading.along_z
    return result


PATH_POINTS = 10
"""Points per move on which the depth's path in time is followed (midpoint rule; on the
emulator's own path 10 fit a noiseless run's steps to 0.0049899 N RMS, 20 to 0.0049884)."""


@dataclass(frozen=True)
class MotionShape:
    """How far along its path (0..1) the tool is at ``PATH_POINTS`` times of each move."""

    share: np.ndarray
    """(T, M, K) share of the path done at the end of each of K equal time slices."""
    before_end_s: np.ndarray
    """(T, M, K) time from the middle of each slice to in position, s."""


def motion_shape(data: RecordArrays, arm: dict[str, float]) -> MotionShape:
    """The tool's path in time over each recorded move, from the arm's model.

    The emulated arm's own motion on its tick grid (:func:`arm_model.profile`): the move
    ends at its (true) in-position time and began its whole ticks of motion before it (never
    before the command was recorded). The share is scaled to reach 1 at in position (the
    depth there is the reached pose's).
    """
    k = PATH_POINTS
    tick = float(arm.get("tick_s", arm_model.TICK_S))
    found = arm_model.profile(data.move_mm, arm, arm.get("in_position_mm", 0.1),
                              keep_path=True)
    assert found.share is not None  # asked for
    # in position at the whole tick its band crossing falls in; the first tick's motion
    # runs over the tick before it
    ticks = np.ceil(found.ticks[found.inverse] - 1e-9)
    begin = np.maximum(data.in_position_s - ticks * tick, data.start_s)
    total = np.maximum(np.nan_to_num(data.in_position_s - begin), 1e-4)
    offset = total - np.minimum(ticks * tick, total)  # a path cut by the recorded start
    path = found.share
    last = path.shape[1] - 1
    rows = found.inverse
    shares = np.empty((*total.shape, k))
    for i in range(1, k + 1):
        x = np.clip((i * total / k - offset) / tick, 0.0, last)
        low = np.floor(x).astype(int)
        high = np.minimum(low + 1, last)
        part = x - low
        shares[..., i - 1] = path[rows, low] * (1.0 - part) + path[rows, high] * part
    shares = shares / np.maximum(shares[..., -1:], 1e-12)
    dt = total / k
    middles = (np.arange(k) + 0.5)[None, None, :] * dt[..., None]
    return MotionShape(np.clip(shares, 0.0, 1.0), total[..., None] - middles)


def _previous_move(a: np.ndarray) -> np.ndarray:
    """``a`` (T, M), each move's column holding the move before it's (a row's first: its own)."""
    result: np.ndarray = np.concatenate([a[:, :1], a[:, :-1]], axis=1)
    return result


def relaxing_at_bursts(data: RecordArrays, reached_yz: tuple[np.ndarray, np.ndarray],
                       p: SpongeParams, shape: MotionShape,
                       start_yz: tuple[np.ndarray, np.ndarray] | None = None,
                       carried: np.ndarray | None = None) -> np.ndarray:
    """The relaxing part q (mm) averaged over each burst, (T, M).

    Over each move the tool goes from where its motion began to the reached pose
    (``reached_yz``: its Y and Z, mm) along the arm's path in time
    (:func:`motion_shape`), and the signed depth is the surface's under it minus its Y
    at every point; the standard linear solid's q integrates the foam depth's
    changes, decaying with ``tau``, as the emulated sponge does tick by tick. Between
    moves q decays; a positive q is 0 once the tool is out of the foam; a trial starts with
    what the trial before it left (:func:`_left_over`). ``start_yz``: where each move's motion began
    (the last move's lag still closing in on its target; default: the last reached
    pose), ``carried``: q that closing added by this move's in position
    (:func:`predict_means`).
    """
    thick, tau = p.thickness_mm, p.relaxation_time_s
    y, z = reached_yz
    y0, z0 = _previous_move(y), _previous_move(z)
    if start_yz is not None:
        y0[:, 1:], z0[:, 1:] = start_yz[0][:, 1:], start_yz[1][:, 1:]
    share = shape.share
    path = _signed_depth_mm(p, data.passes[..., None], y0[..., None]
                            + share * (y - y0)[..., None],
                            z0[..., None] + share * (z - z0)[..., None])
    previous = _signed_depth_mm(p, data.passes, y0, z0)
    foam_path = law.elastic_depth_mm(p, np.clip(path, 0.0, thick))
    start = law.elastic_depth_mm(p, np.clip(previous, 0.0, thick))[..., None]
    changes = np.diff(np.concatenate([start, foam_path], axis=2), axis=2)
    pushed = np.sum(changes * np.exp(-shape.before_end_s / tau), axis=2)
    foam = foam_path[..., -1]
    begin = data.start_s
    end = data.in_position_s
    previous_end = np.concatenate([np.full((data.trials, 1), np.nan), end[:, :-1]], axis=1)
    keep = np.exp(-np.nan_to_num(np.maximum(0.0, end - previous_end)) / tau)
    keep = np.where(np.isfinite(previous_end) & np.isfinite(begin), keep, 0.0)
    pushed = np.where(data.valid, pushed, 0.0)
    released = foam == 0.0
    if carried is not None:
        pushed = pushed + np.where(data.valid, carried, 0.0)

    def scan(start: np.ndarray) -> np.ndarray:
        q = start
        after: np.ndarray = np.zeros_like(foam)
        for j in range(foam.shape[1]):
            q = q * keep[:, j] + pushed[:, j]
            q = np.where(released[:, j] & (q > 0.0), 0.0, q)
            after[:, j] = q
        return after

    after = scan(np.zeros(data.trials))
    left = _left_over(data, after, tau)
    if np.any(left != 0.0):  # added at each row's first move (its keep there is 0)
        pushed = pushed.copy()
        pushed[np.arange(data.trials), np.argmax(data.valid, axis=1)] += left
        after = scan(np.zeros(data.trials))
    b0 = np.nan_to_num(data.burst_start_s)
    span = np.nan_to_num(data.burst_span_s)
    decay = np.exp(-np.maximum(0.0, b0 - np.nan_to_num(end)) / tau)
    with np.errstate(invalid="ignore", divide="ignore"):
        average = np.where(span > 0, tau / span * (1 - np.exp(-span / tau)), 1.0)
    result: np.ndarray = after * decay * average
    return result


def _left_over(data: RecordArrays, after: np.ndarray, tau: float) -> np.ndarray:
    """The relaxing part (mm) each row starts with: the row before it left, decayed, (T,).

    Out of contact the emulated sponge zeroes a positive q only (``Sponge._evolve_at``): the
    retreat that ends a trial eases the foam off and leaves q negative (the foam still
    recovering), which decays with ``tau`` over the travel to the next trial's first contact.
    Hidden cell 02 of seed 6 (ratio 0.56 over 0.53 s, 45 mm deep): its next trial's first
    contact read 0.06 N (2.5 %) below a model that started every trial relaxed. Carried from
    the previous row when it ended before this one began (rows in time order: a trial's
    records; the first row of a held-out split starts relaxed).
    """
    valid = data.valid & np.isfinite(data.in_position_s)
    rows = np.flatnonzero(valid.any(axis=1))
    result = np.zeros(data.trials)
    if rows.size < 2:
        return result
    last = valid.shape[1] - 1 - np.argmax(valid[:, ::-1], axis=1)
    first = np.argmax(valid, axis=1)
    end = data.in_position_s[np.arange(data.trials), last]
    begin = data.in_position_s[np.arange(data.trials), first]
    q_end = after[np.arange(data.trials), last]
    previous, here = rows[:-1], rows[1:]
    gap = begin[here] - end[previous]
    ok = np.isfinite(gap) & (gap > 0.0)
    result[here[ok]] = q_end[previous[ok]] * np.exp(-gap[ok] / tau)
    return result


def _settling_push_mm(p: SpongeParams, passes: np.ndarray, y: np.ndarray, z: np.ndarray,
                      yb: np.ndarray, zb: np.ndarray, since_s: np.ndarray,
                      lag_s: float) -> np.ndarray:
    """The relaxing part (mm) at the burst from the lag's last approach after in position.

    The foam depth goes from the reached pose's to the burst pose's as
    ``1 - exp(-t / lag)``; the standard linear solid's answer is
    ``change * tau / (tau - lag) * (exp(-t / tau) - exp(-t / lag))``.
    """
    thick, tau = p.thickness_mm, p.relaxation_time_s
    change = (law.elastic_depth_mm(p, np.minimum(law.penetration_mm(p, passes, yb, zb), thick))
              - law.elastic_depth_mm(p, np.minimum(law.penetration_mm(p, passes, y, z), thick)))
    if abs(tau - lag_s) < 1e-9:
        response = since_s / lag_s * np.exp(-since_s / lag_s)
    else:
        response = tau / (tau - lag_s) * (np.exp(-since_s / tau) - np.exp(-since_s / lag_s))
    result: np.ndarray = change * response
    return result


def _signed_depth_mm(p: SpongeParams, passes: np.ndarray, y: np.ndarray, z: np.ndarray
                     ) -> np.ndarray:
    """Surface minus tool Y (mm; -1 beyond the strip's ends)."""
    inside = (z >= p.z_bottom_mm) & (z <= p.z_top_mm)
    result: np.ndarray = np.where(inside, law.surface_y_mm(p, passes, z) - y, -1.0)
    return result


def _closing(data: RecordArrays, p: SpongeParams, shape: MotionShape, y: np.ndarray,
             z: np.ndarray, yc: np.ndarray, zc: np.ndarray, lag_s: float
             ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Where each move's motion began (Y, Z, mm), and the q the last move's closing added.

    After in position the tool goes on from the reached pose toward the target with the
    servo lag, until the next move's motion begins (its in-position time less its
    modelled motion): it starts there, and the relaxing part that closing pushed
    (:func:`_settling_push_mm` at the next motion's start) decays to its in position.
    """
    total = shape.before_end_s[..., 0] / (1.0 - 0.5 / PATH_POINTS)
    end = data.in_position_s
    begin = end - total

    since = np.nan_to_num(np.maximum(0.0, begin - _previous_move(end)))
    since[:, 0] = 0.0
    shrink = np.exp(-since / lag_s) if lag_s > 0 else np.zeros_like(since)
    y0, z0, yc0, zc0 = (_previous_move(a) for a in (y, z, yc, zc))
    ys = yc0 + (y0 - yc0) * shrink
    zs = zc0 + (z0 - zc0) * shrink
    if lag_s <= 0:
        return (ys, zs), np.zeros_like(ys)
    push = _settling_push_mm(p, data.passes, y0, z0, yc0, zc0, np.maximum(since, 1e-12), lag_s)
    push = push * np.exp(-np.nan_to_num(total) / p.relaxation_time_s)
    push[:, 0] = 0.0
    return (ys, zs), np.where(np.isfinite(push), push, 0.0)


HYSTERESIS_POINTS = 4
"""Points per move on which the hysteresis state and the slide follow the tool's path."""


@dataclass(frozen=True)
class ContactState:
    """The sponge's path-dependent state at each burst, (T, M) arrays."""

    hysteresis: np.ndarray
    """The Dahl state s in [-1, 1] (0 out of contact)."""
    slide_y: np.ndarray
    """World Y component of the unit direction of the last slide along the surface."""
    slide_z: np.ndarray
    """World Z component of it (zeros: no slide since the tool touched the foam)."""


def _lagging(commanded: np.ndarray, reached: np.ndarray, since_s: np.ndarray,
             lag_s: float) -> np.ndarray:
    """Where the tool is ``since_s`` after in position: the lag's error decays, (..., 3)."""
    shrink = np.exp(-np.maximum(since_s, 0.0) / lag_s) if lag_s > 0 else np.zeros_like(since_s)
    result: np.ndarray = commanded + (reached - commanded) * shrink[..., None]
    return result


def tool_path_mm(data: RecordArrays, arm: dict[str, float]) -> np.ndarray:
    """The tool's path over each move, (T, M, HYSTERESIS_POINTS + 3, 3) points, mm.

    Move ``j``'s points: where the previous move's chain ended (at its burst, or in
    position without one), where the tool was when this move's motion began (the
    lag's error still decaying toward the previous command), a straight line from
    there to the reached pose, and the pose at the middle of this move's burst. A
    trial's first move starts at its reached pose (:func:`contact_state` starts it
    out of contact).
    """
    lag = arm["lag_s"]
    commanded = np.nan_to_num(data.commanded)
    reached = np.nan_to_num(data.reached)
    end_in_position = np.nan_to_num(data.in_position_s)
    mid = np.nan_to_num(data.burst_start_s + 0.5 * data.burst_span_s)
    at_burst = _lagging(commanded, reached, mid - end_in_position, lag)
    chain_end = np.where(data.has_burst[..., None], at_burst, reached)
    # never after in position (a still step, a hold, has no motion and no start delay)
    began = np.minimum(np.nan_to_num(data.start_s) + arm.get("start_delay_s", 0.0),
                       end_in_position)
    start = reached.copy()
    start[:, 1:] = _lagging(commanded[:, :-1], reached[:, :-1],
                            began[:, 1:] - end_in_position[:, :-1], lag)
    before = reached.copy()
    before[:, 1:] = chain_end[:, :-1]
    k = HYSTERESIS_POINTS
    share = (np.arange(k + 1) / k)[None, None, :, None]
    line = start[:, :, None, :] + share * (reached - start)[:, :, None, :]
    result: np.ndarray = np.concatenate(
        [before[:, :, None, :], line, chain_end[:, :, None, :]], axis=2)
    return result


def contact_state(data: RecordArrays, p: SpongeParams, arm: dict[str, float],
                  path: np.ndarray | None = None) -> ContactState:
    """The hysteresis state and the last slide at each burst, as the emulated sponge has them.

    The emulated sponge updates both at every pose the arm reports
    (``Sponge._follow_move``): the foam depth's change and the travel along the
    surface from the last pose feed ``hysteresis_step``'s closed form
    (``hysteresis_target``); a piece of motion that ``slides`` along the surface
    sets the slide's direction (``slide_direction``); out of contact both are 0. Here the pieces
    are those of :func:`tool_path_mm` (``path``, computed when not given), each
    move's pieces composed as one affine map of s, then a scan over the moves.
    A trial starts out of contact (the tool comes from the retract plane).
    """
    path = path if path is not None else tool_path_mm(data, arm)
    passes = data.passes[..., None]
    y, z = path[..., 1], path[..., 2]
    depth = law.penetration_mm(p, passes, y, z)
    depth[:, 0, 0] = 0.0  # a trial starts out of contact
    inside = depth > 0.0
    foam = np.minimum(depth, p.thickness_mm)
    step = np.diff(path, axis=2)
    along_mm = law.along_surface_mm(p, step, z[..., 1:])
    along = np.linalg.norm(along_mm, axis=-1)
    slides = law.slides(along, np.linalg.norm(step, axis=-1))
    contact_after = inside[..., 1:]
    moved = data.valid[..., None]
    trials, moves = data.valid.shape
    hysteresis = np.zeros((trials, moves))
    if p.hysteresis_loss != 0.0:
        target, rate = law.hysteresis_target(p, np.diff(foam, axis=2),
                                             np.where(slides, along, 0.0))
        keep = np.exp(-rate)
        keep = np.where(contact_after, keep, 0.0)  # out of contact: s = 0
        push = np.where(contact_after, target * (1.0 - keep), 0.0)
        keep = np.where(moved, keep, 1.0)
        push = np.where(moved, push, 0.0)
        later = np.concatenate([np.cumprod(keep[..., :0:-1], axis=2)[..., ::-1],
                                np.ones((trials, moves, 1))], axis=2)
        gain = later[..., 0] * keep[..., 0]
        offset = np.sum(push * later, axis=2)
        s = np.zeros(trials)
        for j in range(moves):
            s = gain[:, j] * s + offset[:, j]
            hysteresis[:, j] = s
    slide_y = np.zeros((trials, moves))
    slide_z = np.zeros((trials, moves))
    if p.friction_coefficient != 0.0:
        event = (slides & contact_after) | ~contact_after
        event &= moved
        pieces = event.shape[2]
        last = pieces - 1 - np.argmax(event[..., ::-1], axis=2)
        any_event = event.any(axis=2)
        pick = np.take_along_axis
        index = last[..., None]
        with np.errstate(invalid="ignore", divide="ignore"):
            unit_y = along_mm[..., 1] / along
            unit_z = along_mm[..., 2] / along
        held = pick(contact_after, index, axis=2)[..., 0]
        new_y = np.where(held, pick(unit_y, index, axis=2)[..., 0], 0.0)
        new_z = np.where(held, pick(unit_z, index, axis=2)[..., 0], 0.0)
        ty, tz = np.zeros(trials), np.zeros(trials)
        for j in range(moves):
            ty = np.where(any_event[:, j], new_y[:, j], ty)
            tz = np.where(any_event[:, j], new_z[:, j], tz)
            slide_y[:, j], slide_z[:, j] = ty, tz
    return ContactState(hysteresis, slide_y, slide_z)


CONTACT_KEYS = ("surface_y_mm", "surface_slope", "waviness_mm", "waviness_wavelength_mm",
                "z_top_mm", "z_bottom_mm", "thickness_mm", "set_mm", "set_passes",
                "hysteresis_depth_mm", "hysteresis_travel_mm")
"""The sponge parameters :func:`contact_state` depends on (not h, mu or the stiffness)."""


class ToolPath:
    """A run's tool path (:func:`tool_path_mm`) and its last :func:`contact_state`.

    A fit varies one parameter at a time; most (stiffness, relaxation, h, mu)
    leave the path's contact state as it was, so the last one is kept.
    """

    def __init__(self, data: RecordArrays, arm: dict[str, float]) -> None:
        self.data = data
        self.points = tool_path_mm(data, arm)
        self._key: tuple[float, ...] | None = None
        self._state: ContactState | None = None

    def contact(self, p: SpongeParams) -> ContactState:
        """:func:`contact_state` of the sponge ``p`` on this path."""
        key = (*(getattr(p, k) for k in CONTACT_KEYS), p.hysteresis_loss != 0.0,
               p.friction_coefficient != 0.0)
        if key != self._key or self._state is None:
            self._state = contact_state(self.data, p, {}, self.points)
            self._key = key
        return self._state


def path_dependent(p: SpongeParams) -> bool:
    """True when the sponge has hysteresis or friction (the forward model needs its path)."""
    return p.hysteresis_loss != 0.0 or p.friction_coefficient != 0.0


def predict_means(data: RecordArrays, p: SpongeParams, arm: dict[str, float],
                  reading: Reading, shape: MotionShape | None = None,
                  path: ToolPath | None = None) -> np.ndarray:
    """Predicted burst means (T, M), N; NaN where no burst was read.

    ``shape`` is :func:`motion_shape` of ``data`` and ``arm``, ``path`` its
    :class:`ToolPath` (each computed when needed and not given: pass them when
    predicting many times with one arm). A sample reads the cell as the last motion
    tick before it left it (the emulated cell advances on its tick grid): the bursts
    are read half a tick earlier than their times, on average.
    """
    tick = float(arm.get("tick_s", arm_model.TICK_S))
    data = dataclasses.replace(data, burst_start_s=data.burst_start_s - 0.5 * tick)
    passes = data.passes
    lag_s = arm["lag_s"]
    y = np.where(data.valid, data.reached[..., 1], 1e9)
    z = np.where(data.valid, data.reached[..., 2], 0.0)
    commanded = data.commanded
    yc = np.where(data.valid, commanded[..., 1], 1e9)
    zc = np.where(data.valid, commanded[..., 2], 0.0)
    if p.relaxation_ratio > 0.0:
        shape = shape if shape is not None else motion_shape(data, arm)
        start_yz, carried = _closing(data, p, shape, y, z, yc, zc, lag_s)
        relaxing = relaxing_at_bursts(data, (y, z), p, shape, start_yz, carried)
    else:
        relaxing = np.zeros_like(y)
    burst = data.has_burst
    mid = np.nan_to_num(data.burst_start_s + 0.5 * data.burst_span_s)
    since = np.maximum(0.0, mid - np.nan_to_num(data.in_position_s))
    shrink = np.exp(-since / lag_s) if lag_s > 0 else np.zeros_like(since)
    yb = commanded[..., 1] + (data.reached[..., 1] - commanded[..., 1]) * shrink
    zb = commanded[..., 2] + (data.reached[..., 2] - commanded[..., 2]) * shrink
    yb, zb = np.where(burst, yb, 1e9), np.where(burst, zb, 0.0)
    if p.relaxation_ratio > 0.0 and lag_s > 0:
        relaxing = relaxing + _settling_push_mm(p, passes, y, z, yc, zc, since, lag_s)
    contact = None
    if path_dependent(p):
        contact = (path if path is not None else ToolPath(data, arm)).contact(p)
    force = recorded_force_n(p, passes, yb, zb, relaxing, reading, contact)
    return np.where(burst, force, np.nan)


def within_burst_variance(data: RecordArrays, p: SpongeParams, arm: dict[str, float],
                          reading: Reading) -> np.ndarray:
    """The modelled force's own variance about each burst's mean, (T, M), N^2.

    0 where no burst was read or the model does not predict one. A burst read while the
    force still moves (the foam relaxing after a step, the lag's last approach after in
    position) spreads its samples beyond the sensor's noise. The force at the burst's
    first, middle and last sample (:func:`predict_means` at each, span 0), the parabola
    through them sampled at the burst's ``count`` even times.
    """
    zero = np.zeros_like(data.burst_span_s)
    points = [predict_means(dataclasses.replace(data, burst_start_s=data.burst_start_s
                                                + share * data.burst_span_s, burst_span_s=zero),
                            p, arm, reading) for share in (0.0, 0.5, 1.0)]
    stacked = np.stack(points, axis=-1)  # (T, M, 3)
    ends = np.nan_to_num(stacked)
    result = np.zeros_like(data.burst_span_s)
    counts = np.where(data.has_burst & np.isfinite(stacked).all(axis=-1), data.count, 0)
    for n in np.unique(counts[counts > 1]):
        t = np.linspace(0.0, 1.0, int(n))
        basis = np.stack([2 * (t - 0.5) * (t - 1), -4 * t * (t - 1), 2 * t * (t - 0.5)], axis=1)
        centred = basis - basis.mean(axis=0)  # the samples about their mean, per end value
        at = counts == n
        samples = ends[at] @ centred.T  # (bursts, n)
        result[at] = np.mean(samples**2, axis=1)
    return result


def predict_in_position_s(distance: np.ndarray, arm: dict[str, float],
                          band_mm: float, speed_mm_s: np.ndarray | None = None) -> np.ndarray:
    """Predicted time from command to in position (s) for moves of ``distance`` mm.

    The emulated arm's tick-grid motion, its mean over the command's phase
    (:func:`arm_model.in_position_s`); ``speed_mm_s``: each move's own speed, mm/s.
    """
    return arm_model.in_position_s(distance, arm, band_mm, speed_mm_s)


def mean_sample_period_s(data: RecordArrays) -> float:
    """The bursts' mean sample period, s (NaN when no burst has two samples)."""
    many = data.has_burst & (data.count > 1)
    if not many.any():
        return math.nan
    return float(np.mean(data.burst_span_s[many] / (data.count[many] - 1)))
