"""The twin's forward model: the emulated sponge and arm, vectorised over a run's trials.

Force
-----
The same law as :mod:`forcelearn.emulators.physics.sponge` (a test checks the
two agree point by point): surface ``surface_y(z, n)`` and stiffness
``k(z, n)`` after ``n`` passes, a standard linear solid's relaxing part ``q``
and the rigid backing beyond the foam. The depth is taken to change linearly
from one reached pose to the next while the arm moves (from the command plus
the start delay to the recorded in-position time), for which ``q`` is exact;
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
The time from a command to in position: the start delay, a trapezoidal path
(acceleration, speed) over the commanded distance, and the first-order servo
lag's remaining error decaying into the in-position band, in continuous
time (the emulator's tick grid adds a near-constant few ms, which the fit
measures on the emulator itself: :func:`forcelearn.tools.twin.arm.emulator_delay_s`).

Units: mm, s, N, passes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from forcelearn.devices import quaternion_to_matrix
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


def surface_y_mm(p: dict[str, float], passes: np.ndarray, z_mm: np.ndarray) -> np.ndarray:
    """:func:`forcelearn.emulators.physics.sponge.surface_y_mm`, over arrays."""
    travelled = p["z_top_mm"] - z_mm
    wave = p["waviness_mm"] * np.sin(2 * np.pi * travelled / p["waviness_wavelength_mm"])
    sunk = p["set_mm"] * (1 - np.exp(-passes / p["set_passes"]))
    return p["surface_y_mm"] + p["surface_slope"] * travelled + wave - sunk


def surface_dy_dz(p: dict[str, float], z_mm: np.ndarray) -> np.ndarray:
    """dY/dZ of the surface at ``z_mm``."""
    travelled = p["z_top_mm"] - z_mm
    k = 2 * np.pi / p["waviness_wavelength_mm"]
    return -p["surface_slope"] - p["waviness_mm"] * k * np.cos(k * travelled)


def stiffness_n_per_mm(p: dict[str, float], passes: np.ndarray, z_mm: np.ndarray) -> np.ndarray:
    """:func:`forcelearn.emulators.physics.sponge.stiffness_n_per_mm`, over arrays."""
    travelled = p["z_top_mm"] - z_mm
    variation = p["stiffness_variation"] * np.cos(
        2 * np.pi * travelled / p["stiffness_wavelength_mm"]
    )
    softened = 1 - p["softening"] * (1 - np.exp(-passes / p["softening_passes"]))
    return p["stiffness_n_per_mm"] * (1 + variation) * softened


def depth_mm(p: dict[str, float], passes: np.ndarray, y_mm: np.ndarray,
             z_mm: np.ndarray) -> np.ndarray:
    """Penetration (mm, >= 0) of tool points; 0 off the strip."""
    inside = (z_mm >= p["z_bottom_mm"]) & (z_mm <= p["z_top_mm"])
    return np.where(inside, np.maximum(0.0, surface_y_mm(p, passes, z_mm) - y_mm), 0.0)


def elastic_mm(p: dict[str, float], foam_mm: np.ndarray) -> np.ndarray:
    """The foam's elastic depth u (mm): ``d_f (d_f / d_ref) ** (n - 1)``; ``d_f`` at n = 1.

    ``n`` is ``stiffening_exponent`` and ``d_ref`` ``stiffening_reference_mm`` of the
    nonlinear foam (absent from an emulator without them: the linear foam).
    """
    exponent = p.get("stiffening_exponent", 1.0)
    if exponent == 1.0:
        return foam_mm
    reference = p.get("stiffening_reference_mm", 10.0)
    positive = np.maximum(foam_mm, 1e-12)
    result: np.ndarray = np.where(foam_mm > 0.0,
                                  positive * (positive / reference) ** (exponent - 1.0), 0.0)
    return result


def normal_force_n(p: dict[str, float], passes: np.ndarray, y_mm: np.ndarray,
                   z_mm: np.ndarray, relaxing_mm: np.ndarray | float,
                   reading: Reading, contact: ContactState | None = None) -> np.ndarray:
    """The recorded normal force (N) of tool points with relaxing part ``relaxing_mm``.

    ``contact`` (:func:`contact_state`) adds the hysteresis factor ``1 + h s`` on the
    foam's force and the friction ``-mu N t`` along the last slide; None: neither.
    """
    depth = depth_mm(p, passes, y_mm, z_mm)
    foam = np.maximum(0.0, elastic_mm(p, np.minimum(depth, p["thickness_mm"]))
                      + p["relaxation_ratio"]
                      * relaxing_mm)
    normal = stiffness_n_per_mm(p, passes, z_mm) * foam
    if contact is not None and p.get("hysteresis_loss", 0.0) != 0.0:
        normal = normal * (1.0 + p["hysteresis_loss"] * contact.hysteresis)
    normal = normal + p["backing_n_per_mm"] * np.maximum(0.0, depth - p["thickness_mm"])
    normal = np.where(depth > 0.0, normal, 0.0)
    slope = surface_dy_dz(p, z_mm)
    result: np.ndarray = normal * (reading.along_y - reading.along_z * slope) / np.sqrt(
        1.0 + slope * slope
    )
    mu = p.get("friction_coefficient", 0.0)
    if contact is not None and mu != 0.0:
        result = result - mu * normal * (reading.along_y * contact.slide_y
                                         + reading.along_z * contact.slide_z)
    return result


PATH_POINTS = 20
"""Points per move on which the depth's path in time is followed (midpoint rule)."""


@dataclass(frozen=True)
class MotionShape:
    """How far along its path (0..1) the tool is at ``PATH_POINTS`` times of each move."""

    share: np.ndarray
    """(T, M, K) share of the path done at the end of each of K equal time slices."""
    before_end_s: np.ndarray
    """(T, M, K) time from the middle of each slice to in position, s."""


def motion_shape(data: RecordArrays, arm: dict[str, float]) -> MotionShape:
    """The tool's path in time over each recorded move, from the arm's model.

    The move ends at its recorded in-position time and began the arm model's
    motion time before it (never before the command): the recorded start also
    holds the link's time to send the command, which the motion does not. The
    reference runs the trapezoidal profile over the commanded distance; the tool
    follows it through the first-order lag (the share is scaled to reach 1).
    """
    k = PATH_POINTS
    distance = np.nan_to_num(data.move_mm)
    motion_s = predict_in_position_s(distance, {**arm, "start_delay_s": 0.0},
                                     arm.get("in_position_mm", 0.1))
    begin = np.maximum(data.in_position_s - motion_s, data.start_s)
    total = np.maximum(np.nan_to_num(data.in_position_s - begin), 1e-4)
    speed, accel, lag = arm["default_speed_mm_s"], arm["accel_mm_s2"], arm["lag_s"]
    cruise = distance >= speed * speed / accel
    t_acc = np.where(cruise, speed / accel, np.sqrt(distance / accel))
    t_ref = np.maximum(2 * t_acc + np.where(cruise, distance / speed - speed / accel, 0.0),
                       1e-6)
    dt = total / k
    keep = np.exp(-dt / lag) if lag > 0 else np.zeros_like(dt)
    tool = np.zeros_like(total)
    shares = np.empty((*total.shape, k))
    for i in range(1, k + 1):
        t = np.minimum(i * dt, t_ref)
        travelled = np.where(
            t <= t_acc, 0.5 * accel * t * t,
            np.where(t <= t_ref - t_acc, 0.5 * accel * t_acc**2 + accel * t_acc * (t - t_acc),
                     distance - 0.5 * accel * (t_ref - t) ** 2),
        )
        reference = np.where(distance > 0, travelled / np.maximum(distance, 1e-12), 1.0)
        tool = reference + (tool - reference) * keep
        shares[..., i - 1] = tool
    shares = shares / np.maximum(shares[..., -1:], 1e-12)
    middles = (np.arange(k) + 0.5)[None, None, :] * dt[..., None]
    return MotionShape(np.clip(shares, 0.0, 1.0), total[..., None] - middles)


def relaxing_at_bursts(data: RecordArrays, depth_signed: np.ndarray, p: dict[str, float],
                       shape: MotionShape) -> np.ndarray:
    """The relaxing part q (mm) averaged over each burst, (T, M).

    Over each move the signed depth (surface minus tool Y) goes from the previous
    reached pose's to this one's along the tool's path in time
    (:func:`motion_shape`); the standard linear solid's q integrates the foam
    depth's changes, decaying with ``tau``, as the emulated sponge does tick by
    tick. Between moves q decays; it is 0 once the tool is out of the foam; trials
    start relaxed (the tool comes from free space).
    """
    thick, tau = p["thickness_mm"], p["relaxation_time_s"]
    previous = np.concatenate([depth_signed[:, :1], depth_signed[:, :-1]], axis=1)
    path = previous[..., None] + shape.share * (depth_signed - previous)[..., None]
    foam_path = elastic_mm(p, np.clip(path, 0.0, thick))
    start = elastic_mm(p, np.clip(previous, 0.0, thick))[..., None]
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
    q = np.zeros(data.trials)
    after = np.zeros_like(foam)
    for j in range(foam.shape[1]):
        q = q * keep[:, j] + pushed[:, j]
        q = np.where(released[:, j] & (q > 0.0), 0.0, q)
        after[:, j] = q
    b0 = np.nan_to_num(data.burst_start_s)
    span = np.nan_to_num(data.burst_span_s)
    decay = np.exp(-np.maximum(0.0, b0 - np.nan_to_num(end)) / tau)
    with np.errstate(invalid="ignore", divide="ignore"):
        average = np.where(span > 0, tau / span * (1 - np.exp(-span / tau)), 1.0)
    result: np.ndarray = after * decay * average
    return result


def _settling_push_mm(p: dict[str, float], passes: np.ndarray, y: np.ndarray, z: np.ndarray,
                      yb: np.ndarray, zb: np.ndarray, since_s: np.ndarray,
                      lag_s: float) -> np.ndarray:
    """The relaxing part (mm) at the burst from the lag's last approach after in position.

    The foam depth goes from the reached pose's to the burst pose's as
    ``1 - exp(-t / lag)``; the standard linear solid's answer is
    ``change * tau / (tau - lag) * (exp(-t / tau) - exp(-t / lag))``.
    """
    thick, tau = p["thickness_mm"], p["relaxation_time_s"]
    change = (elastic_mm(p, np.minimum(depth_mm(p, passes, yb, zb), thick))
              - elastic_mm(p, np.minimum(depth_mm(p, passes, y, z), thick)))
    if abs(tau - lag_s) < 1e-9:
        response = since_s / lag_s * np.exp(-since_s / lag_s)
    else:
        response = tau / (tau - lag_s) * (np.exp(-since_s / tau) - np.exp(-since_s / lag_s))
    result: np.ndarray = change * response
    return result


HYSTERESIS_POINTS = 4
"""Points per move on which the hysteresis state and the slide follow the tool's path."""
SLIDE_MIN_FRACTION = 0.1
"""A path piece slides when its part along the surface is at least this fraction of it
(:data:`forcelearn.emulators.physics.sponge.SLIDE_MIN_FRACTION`)."""


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
    began = np.nan_to_num(data.start_s) + arm.get("start_delay_s", 0.0)
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


def contact_state(data: RecordArrays, p: dict[str, float], arm: dict[str, float],
                  path: np.ndarray | None = None) -> ContactState:
    """The hysteresis state and the last slide at each burst, as the emulated sponge has them.

    The emulated sponge updates both at every pose the arm reports
    (``Sponge._follow_move``): the foam depth's change and the travel along the
    surface from the last pose feed ``hysteresis_step``'s closed form; a piece of
    motion at least ``SLIDE_MIN_FRACTION`` along the surface sets the slide's
    direction (``slide_direction``); out of contact both are 0. Here the pieces
    are those of :func:`tool_path_mm` (``path``, computed when not given), each
    move's pieces composed as one affine map of s, then a scan over the moves.
    A trial starts out of contact (the tool comes from the retract plane).
    """
    path = path if path is not None else tool_path_mm(data, arm)
    passes = data.passes[..., None]
    y, z = path[..., 1], path[..., 2]
    depth = depth_mm(p, passes, y, z)
    depth[:, 0, 0] = 0.0  # a trial starts out of contact
    inside = depth > 0.0
    foam = np.minimum(depth, p["thickness_mm"])
    step = np.diff(path, axis=2)
    slope = surface_dy_dz(p, z[..., 1:])
    norm = np.sqrt(1.0 + slope * slope)
    normal_y, normal_z = 1.0 / norm, -slope / norm
    across = step[..., 1] * normal_y + step[..., 2] * normal_z
    length2 = np.sum(step * step, axis=-1)
    along = np.sqrt(np.maximum(length2 - across * across, 0.0))
    slides = (along >= SLIDE_MIN_FRACTION * np.sqrt(length2)) & (along >= 1e-9)
    contact_after = inside[..., 1:]
    moved = data.valid[..., None]
    trials, moves = data.valid.shape
    h = p.get("hysteresis_loss", 0.0)
    hysteresis = np.zeros((trials, moves))
    if h != 0.0:
        change = np.diff(foam, axis=2)
        a = np.abs(change) / p["hysteresis_depth_mm"]
        b = np.where(slides, along, 0.0) / p["hysteresis_travel_mm"]
        rate = a + b
        sign = np.where(change > 0.0, 1.0, -1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            target = np.where(rate > 0.0, (a * sign + b) / rate, 0.0)
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
    if p.get("friction_coefficient", 0.0) != 0.0:
        event = (slides & contact_after) | ~contact_after
        event &= moved
        pieces = event.shape[2]
        last = pieces - 1 - np.argmax(event[..., ::-1], axis=2)
        any_event = event.any(axis=2)
        pick = np.take_along_axis
        index = last[..., None]
        with np.errstate(invalid="ignore", divide="ignore"):
            unit_y = (step[..., 1] - across * normal_y) / along
            unit_z = (step[..., 2] - across * normal_z) / along
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

    def contact(self, p: dict[str, float]) -> ContactState:
        """:func:`contact_state` of the sponge ``p`` on this path."""
        key = (*(p[k] for k in CONTACT_KEYS), p.get("hysteresis_loss", 0.0) != 0.0,
               p.get("friction_coefficient", 0.0) != 0.0)
        if key != self._key or self._state is None:
            self._state = contact_state(self.data, p, {}, self.points)
            self._key = key
        return self._state


def path_dependent(p: dict[str, float]) -> bool:
    """True when the sponge has hysteresis or friction (the forward model needs its path)."""
    return p.get("hysteresis_loss", 0.0) != 0.0 or p.get("friction_coefficient", 0.0) != 0.0


def predict_means(data: RecordArrays, p: dict[str, float], arm: dict[str, float],
                  reading: Reading, shape: MotionShape | None = None,
                  path: ToolPath | None = None) -> np.ndarray:
    """Predicted burst means (T, M), N; NaN where no burst was read.

    ``shape`` is :func:`motion_shape` of ``data`` and ``arm``, ``path`` its
    :class:`ToolPath` (each computed when needed and not given: pass them when
    predicting many times with one arm).
    """
    passes = data.passes
    lag_s = arm["lag_s"]
    y = np.where(data.valid, data.reached[..., 1], 1e9)
    z = np.where(data.valid, data.reached[..., 2], 0.0)
    if p["relaxation_ratio"] > 0.0:
        inside = (z >= p["z_bottom_mm"]) & (z <= p["z_top_mm"])
        signed = np.where(inside, surface_y_mm(p, passes, z) - y, -1.0)
        shape = shape if shape is not None else motion_shape(data, arm)
        relaxing = relaxing_at_bursts(data, signed, p, shape)
    else:
        relaxing = np.zeros_like(y)
    burst = data.has_burst
    mid = np.nan_to_num(data.burst_start_s + 0.5 * data.burst_span_s)
    since = np.maximum(0.0, mid - np.nan_to_num(data.in_position_s))
    shrink = np.exp(-since / lag_s) if lag_s > 0 else np.zeros_like(since)
    commanded = data.commanded
    yb = commanded[..., 1] + (data.reached[..., 1] - commanded[..., 1]) * shrink
    zb = commanded[..., 2] + (data.reached[..., 2] - commanded[..., 2]) * shrink
    yb, zb = np.where(burst, yb, 1e9), np.where(burst, zb, 0.0)
    if p["relaxation_ratio"] > 0.0 and lag_s > 0:
        relaxing = relaxing + _settling_push_mm(p, passes, y, z, yb, zb, since, lag_s)
    contact = None
    if path_dependent(p):
        contact = (path if path is not None else ToolPath(data, arm)).contact(p)
    force = normal_force_n(p, passes, yb, zb, relaxing, reading, contact)
    return np.where(burst, force, np.nan)


def _lag_error_mm(distance: np.ndarray, speed: float, accel: float, lag: float,
                  points: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """Path time (s) and the lagging tool's error (mm) when the path stops, per distance."""
    reach = speed * speed / accel
    cruise = distance >= reach
    t_acc = np.where(cruise, speed / accel, np.sqrt(np.maximum(distance, 0.0) / accel))
    t_cruise = np.where(cruise, distance / speed - speed / accel, 0.0)
    total = 2 * t_acc + t_cruise
    if lag <= 0:
        return total, np.zeros_like(distance)
    u = np.linspace(0.0, 1.0, points)
    s = u * total[..., None]
    peak = accel * t_acc[..., None]
    velocity = np.minimum(np.minimum(accel * s, peak),
                          np.maximum(0.0, accel * (total[..., None] - s)))
    kernel = np.exp(-(total[..., None] - s) / lag)
    error = np.trapezoid(velocity * kernel, s, axis=-1)
    return total, error


def predict_in_position_s(distance: np.ndarray, arm: dict[str, float],
                          band_mm: float) -> np.ndarray:
    """Predicted time from command to in position (s) for moves of ``distance`` mm."""
    total, error = _lag_error_mm(distance, arm["default_speed_mm_s"], arm["accel_mm_s2"],
                                 arm["lag_s"])
    settle = arm["lag_s"] * np.log(np.maximum(error, band_mm) / band_mm)
    result: np.ndarray = arm["start_delay_s"] + total + settle
    return result


def mean_sample_period_s(data: RecordArrays) -> float:
    """The bursts' mean sample period, s (NaN when no burst has two samples)."""
    many = data.has_burst & (data.count > 1)
    if not many.any():
        return math.nan
    return float(np.mean(data.burst_span_s[many] / (data.count[many] - 1)))
