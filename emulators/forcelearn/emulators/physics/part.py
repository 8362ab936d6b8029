"""Emulated part geometry: where a tool presses into a plane, cylinder, sphere or height map.

Description
-----------
A part is a rigid surface with an outward normal (pointing out of the material,
towards the tool). For a tool whose tip is a ball of radius ``r`` (a roller or
pad seen across its contact; ``r = 0``: a point) centred at ``c``:

=================  ==========================================================
signed distance s  of ``c`` from the surface, mm, > 0 outside the material
depth d            ``r + offset_mm - s`` mm: > 0 is penetration (compression
                   of a cover of thickness ``offset_mm``), <= 0 a gap
normal n           outward unit normal at the surface point nearest ``c``
surface point      that nearest point, moved out by ``offset_mm`` along n
=================  ==========================================================

``offset_mm`` moves the surface out along its normal: a foam cover of that
thickness has its skin there, so ``d`` is the foam's compression and
``d - offset_mm`` the depth into the rigid part. This is exact for the plane,
the cylinder and the sphere (their offset surfaces are of the same kind).

Shapes (frozen parameter dataclasses, validated on construction):

==============  ===============================================================
``Plane``       ``point_mm`` on it, ``normal`` (outward; normalised)
``Cylinder``    ``point_mm`` on the axis, ``axis``, ``radius_mm``; ``concave``:
                the material is outside the radius (pressing on the inside of
                a pipe or a trough), the outward normal points to the axis
``Sphere``      ``centre_mm``, ``radius_mm``; ``concave``: a spherical bowl
``Heightmap``   heights (mm) on a regular grid over a base plane: ``heights_mm[i,
                j]`` at ``origin_mm + i*spacing_mm*u_axis + j*spacing_mm*v_axis``,
                ``v_axis = normal x u_axis``; ``interpolation`` "linear"
                (bilinear) or "cubic" (bicubic spline, scipy)
==============  ===============================================================

The height map's nearest point is found by a fixed-point iteration from the
point straight below ``c``: at the current foot ``f = (u, v, h(u, v))`` with
normal ``n``, ``s = (c - f) . n`` and the next foot is below ``c - s n``
(``FOOT_ITERATIONS`` steps; exact after one on a plane, and converging while
``|s|`` is below the map's radius of curvature, as for the thickness of a foam
cover). Beyond the grid there is no surface: ``d = -inf`` (never in contact),
``n`` the base normal.

The depth is what a foam law takes as its compression (``d`` in mm); the force
acts along ``n``. Nothing here knows the tool, the sensor or a wire.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.spatial.transform import Rotation

Vector = tuple[float, float, float]

FOOT_ITERATIONS = 4
"""Fixed-point steps towards the height map's foot point (exact after one on a plane)."""


def _unit(vector: Vector, name: str) -> Vector:
    v = np.asarray(vector, dtype=float)
    norm = float(np.linalg.norm(v)) if v.shape == (3,) else 0.0
    if not (np.all(np.isfinite(v)) and norm > 0):
        raise ValueError(f"{name} must be a non-zero finite 3-vector, got {vector}")
    return (float(v[0] / norm), float(v[1] / norm), float(v[2] / norm))


def _point(vector: Vector, name: str) -> Vector:
    v = np.asarray(vector, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be a finite 3-vector (mm), got {vector}")
    return (float(v[0]), float(v[1]), float(v[2]))


def _positive(value: float, name: str) -> None:
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be > 0 (mm), got {value}")


@dataclass(frozen=True)
class Plane:
    """A flat part: a point on its surface (mm) and its outward normal (normalised here)."""

    point_mm: Vector
    normal: Vector

    def __post_init__(self) -> None:
        object.__setattr__(self, "point_mm", _point(self.point_mm, "plane point_mm"))
        object.__setattr__(self, "normal", _unit(self.normal, "plane normal"))


@dataclass(frozen=True)
class Cylinder:
    """A cylinder: a point on its axis (mm), the axis direction, its radius (mm), concave."""

    point_mm: Vector
    axis: Vector
    radius_mm: float
    concave: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "point_mm", _point(self.point_mm, "cylinder point_mm"))
        object.__setattr__(self, "axis", _unit(self.axis, "cylinder axis"))
        _positive(self.radius_mm, "cylinder radius_mm")


@dataclass(frozen=True)
class Sphere:
    """A sphere: centre (mm) and radius (mm); ``concave`` for a spherical bowl."""

    centre_mm: Vector
    radius_mm: float
    concave: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre_mm", _point(self.centre_mm, "sphere centre_mm"))
        _positive(self.radius_mm, "sphere radius_mm")


@dataclass(frozen=True)
class Heightmap:
    """Heights (mm) on a regular grid over a base plane (see the module docstring)."""

    heights_mm: np.ndarray
    origin_mm: Vector
    spacing_mm: float
    normal: Vector = (0.0, 0.0, 1.0)
    u_axis: Vector = (1.0, 0.0, 0.0)
    interpolation: Literal["linear", "cubic"] = "linear"
    _spline: RectBivariateSpline = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        heights = np.array(self.heights_mm, dtype=float)
        degree = {"linear": 1, "cubic": 3}.get(self.interpolation)
        if degree is None:
            raise ValueError(f"heightmap interpolation must be 'linear' or 'cubic', "
                             f"got {self.interpolation!r}")
        if heights.ndim != 2 or min(heights.shape) < degree + 1:
            raise ValueError(f"heightmap heights must be a 2-D grid of at least {degree + 1} x "
                             f"{degree + 1} points for {self.interpolation}, got {heights.shape}")
        if not np.all(np.isfinite(heights)):
            raise ValueError("heightmap heights must be finite numbers (mm)")
        _positive(self.spacing_mm, "heightmap spacing_mm")
        normal = _unit(self.normal, "heightmap normal")
        u = np.asarray(_unit(self.u_axis, "heightmap u_axis"))
        u = u - np.dot(u, normal) * np.asarray(normal)
        if np.linalg.norm(u) < 1e-6:
            raise ValueError("heightmap u_axis must not be parallel to its normal")
        heights.flags.writeable = False
        object.__setattr__(self, "heights_mm", heights)
        object.__setattr__(self, "origin_mm", _point(self.origin_mm, "heightmap origin_mm"))
        object.__setattr__(self, "normal", normal)
        object.__setattr__(self, "u_axis", _unit(tuple(u), "heightmap u_axis"))
        u_grid = np.arange(heights.shape[0]) * self.spacing_mm
        v_grid = np.arange(heights.shape[1]) * self.spacing_mm
        object.__setattr__(self, "_spline", RectBivariateSpline(
            u_grid, v_grid, heights, kx=degree, ky=degree, s=0))

    @property
    def v_axis(self) -> np.ndarray:
        """The grid's second direction, ``normal x u_axis``."""
        return self._frame[2].copy()

    @functools.cached_property
    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """normal, u_axis, v_axis and origin as arrays, made once (a motion tick's hot path)."""
        normal, u_axis = np.asarray(self.normal), np.asarray(self.u_axis)
        for array in (normal, u_axis):
            array.flags.writeable = False
        v_axis = np.cross(normal, u_axis)
        origin = np.asarray(self.origin_mm)
        v_axis.flags.writeable = origin.flags.writeable = False
        return normal, u_axis, v_axis, origin

    @property
    def extent_mm(self) -> tuple[float, float]:
        """The grid's size along u and v (mm)."""
        rows, columns = self.heights_mm.shape
        return (rows - 1) * self.spacing_mm, (columns - 1) * self.spacing_mm


Part = Plane | Cylinder | Sphere | Heightmap


def load_heights(path: str | Path) -> np.ndarray:
    """A height grid (mm) from a ``.npy`` file or a CSV of numbers (``#`` comments)."""
    path = Path(path)
    try:
        if path.suffix.lower() == ".npy":
            heights = np.load(path, allow_pickle=False)
        else:
            heights = np.loadtxt(path, delimiter=",", comments="#", ndmin=2)
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the height map {path}: {exc}") from exc
    return np.asarray(heights, dtype=float)


@dataclass(frozen=True)
class Contact:
    """Depth (mm, > 0 pressing), outward normal and surface point (mm) for each tip centre."""

    depth_mm: np.ndarray
    normal: np.ndarray
    surface_mm: np.ndarray


def contact(part: Part, centres_mm: np.ndarray, radius_mm: float = 0.0,
            offset_mm: float = 0.0) -> Contact:
    """Where tips of radius ``radius_mm`` centred at ``centres_mm`` ((..., 3) mm) meet ``part``.

    ``offset_mm``: the surface moved out along its normal (a cover's thickness).
    """
    if not (radius_mm >= 0 and offset_mm >= 0):
        raise ValueError(f"radius_mm and offset_mm must be >= 0, got {radius_mm}, {offset_mm}")
    centres = np.asarray(centres_mm, dtype=float)
    if centres.shape[-1:] != (3,):
        raise ValueError(f"centres_mm must have shape (..., 3), got {centres.shape}")
    signed, normal, surface = _distance(part, centres)
    return Contact(radius_mm + offset_mm - signed, normal, surface + offset_mm * normal)


def tip_centres_mm(positions_mm: np.ndarray, quaternions_wxyz: np.ndarray,
                   contact_point_mm: Vector, radius_mm: float,
                   press_axis: Vector = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Centres (mm, base frame) of a tool tip of radius ``radius_mm`` at flange poses.

    ``contact_point_mm`` is the tip's pressing point in the tool (sensor) frame and
    ``press_axis`` the tool-frame direction it presses along; the ball's centre
    lies ``radius_mm`` behind that point. Quaternions are scalar first.
    """
    quaternions = np.asarray(quaternions_wxyz, dtype=float)
    turn = Rotation.from_quat(quaternions.reshape(-1, 4)[:, [1, 2, 3, 0]])
    axis = np.asarray(_unit(press_axis, "press_axis"))
    local = np.asarray(contact_point_mm, dtype=float) - radius_mm * axis
    centres = np.asarray(positions_mm, dtype=float).reshape(-1, 3) + turn.apply(local)
    return np.asarray(centres.reshape(np.shape(positions_mm)), dtype=float)


def _distance(part: Part, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance (mm, > 0 outside), outward normal, nearest surface point."""
    if isinstance(part, Plane):
        n = np.asarray(part.normal)
        signed = (c - np.asarray(part.point_mm)) @ n
        return signed, np.broadcast_to(n, c.shape).copy(), c - signed[..., None] * n
    if isinstance(part, Cylinder):
        a, u = np.asarray(part.point_mm), np.asarray(part.axis)
        along = (c - a) @ u
        foot = a + along[..., None] * u
        radial, dist = _direction(c - foot, _perpendicular(u))
        return _round(part.radius_mm, part.concave, dist, radial, foot)
    if isinstance(part, Sphere):
        centre = np.asarray(part.centre_mm)
        radial, dist = _direction(c - centre, _perpendicular(np.array([0.0, 0.0, 1.0])))
        return _round(part.radius_mm, part.concave, dist, radial,
                      np.broadcast_to(centre, c.shape))
    return _heightmap_point(part, c) if c.ndim == 1 else _heightmap_distance(part, c)


def _perpendicular(axis: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``axis`` (the direction used on the axis itself)."""
    return _perpendicular_of(float(axis[0]), float(axis[1]), float(axis[2])).copy()


@functools.lru_cache(maxsize=16)
def _perpendicular_of(ax: float, ay: float, az: float) -> np.ndarray:
    """:func:`_perpendicular` of one axis, kept (asked at every motion tick of a cell)."""
    axis = np.array([ax, ay, az])
    trial = np.array([1.0, 0.0, 0.0]) if abs(ax) < 0.9 else np.array([0.0, 1.0, 0.0])
    out = np.cross(axis, trial)
    return np.asarray(out / np.linalg.norm(out), dtype=float)


def _direction(vectors: np.ndarray, fallback: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions and lengths of ``vectors``; ``fallback`` where a vector is zero."""
    length = np.linalg.norm(vectors, axis=-1)
    safe = np.where(length[..., None] > 0, vectors / np.maximum(length, 1e-300)[..., None],
                    fallback)
    return safe, length


def _round(radius: float, concave: bool, dist: np.ndarray, radial: np.ndarray,
           foot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    surface = foot + radius * radial
    if concave:
        return radius - dist, -radial, surface
    return dist - radius, radial, surface


def _heightmap_distance(part: Heightmap, c: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                    np.ndarray]:
    n, u_axis, v_axis = np.asarray(part.normal), np.asarray(part.u_axis), part.v_axis
    origin = np.asarray(part.origin_mm)
    relative = c - origin
    u, v, w = relative @ u_axis, relative @ v_axis, relative @ n
    size_u, size_v = part.extent_mm
    inside = (u >= 0) & (u <= size_u) & (v >= 0) & (v <= size_v)
    foot_u, foot_v = np.clip(u, 0, size_u), np.clip(v, 0, size_v)
    for _ in range(FOOT_ITERATIONS):
        height = part._spline.ev(foot_u, foot_v)
        slope_u, slope_v = _slopes(part, foot_u, foot_v)
        stretch = np.sqrt(1.0 + slope_u**2 + slope_v**2)[..., None]
        normal = (n - slope_u[..., None] * u_axis - slope_v[..., None] * v_axis) / stretch
        foot = (origin + foot_u[..., None] * u_axis + foot_v[..., None] * v_axis
                + height[..., None] * n)
        signed = np.einsum("...k,...k->...", c - foot, normal)
        projected = c - signed[..., None] * normal - origin
        foot_u = np.clip(projected @ u_axis, 0, size_u)
        foot_v = np.clip(projected @ v_axis, 0, size_v)
    surface = c - signed[..., None] * normal
    signed = np.where(inside, signed, np.inf)
    normal = np.where(inside[..., None], normal, n)
    surface = np.where(inside[..., None], surface, c - w[..., None] * n)
    return signed, normal, surface


def _heightmap_point(part: Heightmap, c: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
    """:func:`_heightmap_distance` of one point (3,): the same operations in the same order.

    A cell asks for one tip centre at every motion tick, where numpy's per-call cost on
    0-d arrays (``clip``, ``cross``, ``where``) was most of the emulated cell's time; the
    results are bit for bit those of the vectorised form given the same one point (a test
    compares them; a batch's inner products may round differently in the last bit).
    """
    n, u_axis, v_axis, origin = part._frame
    size_u, size_v = part.extent_mm
    relative = c - origin
    u, v, w = relative @ u_axis, relative @ v_axis, relative @ n
    inside = 0 <= u <= size_u and 0 <= v <= size_v
    foot_u, foot_v = min(max(u, 0.0), size_u), min(max(v, 0.0), size_v)
    ev = part._spline.ev
    cubic = part.interpolation == "cubic"
    for _ in range(FOOT_ITERATIONS):
        height = ev(foot_u, foot_v)
        if cubic:
            slope_u, slope_v = ev(foot_u, foot_v, dx=1), ev(foot_u, foot_v, dy=1)
        else:
            slope_u, slope_v = _slopes(part, foot_u, foot_v)
        stretch = np.sqrt(1.0 + slope_u**2 + slope_v**2)
        normal = (n - slope_u * u_axis - slope_v * v_axis) / stretch
        foot = origin + foot_u * u_axis + foot_v * v_axis + height * n
        signed = np.einsum("...k,...k->...", c - foot, normal)
        projected = c - signed * normal - origin
        foot_u = min(max(projected @ u_axis, 0.0), size_u)
        foot_v = min(max(projected @ v_axis, 0.0), size_v)
    if not inside:
        return np.asarray(np.inf), n.copy(), c - w * n
    return np.asarray(signed), normal, c - signed * normal


def _slopes(part: Heightmap, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dh/du and dh/dv: the spline's derivatives (cubic), or differences within a cell (linear).

    A bilinear surface is linear along u at fixed v (and along v at fixed u), so
    a difference across a small step is its exact slope inside a cell; on a
    cell's edge it is the mean of the two sides.
    """
    if part.interpolation == "cubic":
        return part._spline.ev(u, v, dx=1), part._spline.ev(u, v, dy=1)
    size_u, size_v = part.extent_mm
    step = 1e-3 * part.spacing_mm
    u_hi, u_lo = np.minimum(u + step, size_u), np.maximum(u - step, 0.0)
    v_hi, v_lo = np.minimum(v + step, size_v), np.maximum(v - step, 0.0)
    ev = part._spline.ev
    return ((ev(u_hi, v) - ev(u_lo, v)) / (u_hi - u_lo),
            (ev(u, v_hi) - ev(u, v_lo)) / (v_hi - v_lo))
