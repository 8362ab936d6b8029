"""The taught path and the frames it is expressed in.

=========================  =================================================
``positions_mm``           (n, 3) float, base frame, mm
``quaternions_wxyz``       (n, 4) float, scalar first (RAPID's q1..q4 order)
``names``                  the robtarget (or expression) each pose came from
``lines``                  1-based source line of each pose (0: none)
``instructions``           the instruction that used it (``MoveL``, ``CSV``...)
``tool_names``             the tooldata each move named ('' for a CSV)
``tools``                  tooldata declared in the module, by name
``notes``                  what the reader skipped, and why
=========================  =================================================

Quaternions are converted to and from :class:`scipy.spatial.transform.Rotation`
at this module's boundary only; a frame that is the identity passes poses
through untouched, so a path read in the base frame keeps its file's values.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
from scipy.spatial.transform import Rotation

QUATERNION_TOLERANCE = 1e-3
"""Largest ``| |q| - 1 |`` accepted for a taught orientation (assumption: taught robtargets
carry 6+ decimals, so a larger error is a typing mistake, not rounding)."""

_IDENTITY_WXYZ = (1.0, 0.0, 0.0, 0.0)


def rotation_from_wxyz(quaternions_wxyz: np.ndarray) -> Rotation:
    """A scipy Rotation from quaternions, scalar first ((4,) or (n, 4))."""
    q = np.asarray(quaternions_wxyz, dtype=float)
    return Rotation.from_quat(q[..., [1, 2, 3, 0]])


def wxyz_from_rotation(rotation: Rotation) -> np.ndarray:
    """Quaternions (scalar first) of a scipy Rotation, scalar part >= 0."""
    wxyz = np.asarray(rotation.as_quat(), dtype=float)[..., [3, 0, 1, 2]]
    return np.where(wxyz[..., :1] < 0, -wxyz, wxyz)


def quaternion_norm_error(quaternions_wxyz: np.ndarray) -> np.ndarray:
    """``| |q| - 1 |`` of each quaternion (dimensionless)."""
    norms = np.linalg.norm(np.asarray(quaternions_wxyz, dtype=float), axis=-1)
    return np.asarray(np.abs(norms - 1.0), dtype=float)


@dataclass(frozen=True)
class Frame:
    """A rigid frame: origin (mm) and orientation (unit quaternion w, x, y, z) in its parent."""

    position_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quaternion_wxyz: tuple[float, float, float, float] = _IDENTITY_WXYZ

    @property
    def is_identity(self) -> bool:
        """True when the frame neither moves nor turns what it carries."""
        return self.position_mm == (0.0, 0.0, 0.0) and self.quaternion_wxyz == _IDENTITY_WXYZ

    def apply(
        self, positions_mm: np.ndarray, quaternions_wxyz: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Poses given in this frame ((n, 3) mm, (n, 4)) expressed in its parent."""
        positions = np.array(positions_mm, dtype=float)
        quaternions = np.array(quaternions_wxyz, dtype=float)
        if self.is_identity:
            return positions, quaternions
        turn = rotation_from_wxyz(np.array(self.quaternion_wxyz))
        moved = turn.apply(positions) + np.array(self.position_mm)
        return moved, wxyz_from_rotation(turn * rotation_from_wxyz(quaternions))

    def inverse(self) -> Frame:
        """The parent frame expressed in this one."""
        turn = rotation_from_wxyz(np.array(self.quaternion_wxyz)).inv()
        return Frame(_triple(-turn.apply(np.array(self.position_mm))),
                     _quad(wxyz_from_rotation(turn)))

    def then(self, inner: Frame) -> Frame:
        """The frame ``inner`` (given in this frame) expressed in this frame's parent."""
        positions, quaternions = self.apply(
            np.array([inner.position_mm]), np.array([inner.quaternion_wxyz])
        )
        return Frame(_triple(positions[0]), _quad(quaternions[0]))


def _triple(values: np.ndarray) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def _quad(values: np.ndarray) -> tuple[float, float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]), float(values[3]))


@dataclass(frozen=True)
class ToolData:
    """A RAPID ``tooldata``: the TCP frame in the flange frame (mm), load mass (kg), CoG (mm)."""

    robhold: bool
    tcp: Frame
    mass_kg: float
    cog_mm: tuple[float, float, float]


@dataclass(frozen=True)
class TaughtPath:
    """Ordered poses in the robot's base frame (table in the module docstring)."""

    positions_mm: np.ndarray
    quaternions_wxyz: np.ndarray
    names: tuple[str, ...] = ()
    lines: tuple[int, ...] = ()
    source: str = ""
    instructions: tuple[str, ...] = ()
    tool_names: tuple[str, ...] = ()
    tools: Mapping[str, ToolData] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        positions = np.array(self.positions_mm, dtype=float).reshape(-1, 3)
        quaternions = np.array(self.quaternions_wxyz, dtype=float).reshape(-1, 4)
        n = len(positions)
        if len(quaternions) != n:
            raise ValueError(f"{n} positions but {len(quaternions)} quaternions")
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(quaternions))):
            raise ValueError("path poses must be finite numbers")
        positions.flags.writeable = False
        quaternions.flags.writeable = False
        object.__setattr__(self, "positions_mm", positions)
        object.__setattr__(self, "quaternions_wxyz", quaternions)
        for name, default in (("names", ""), ("lines", 0), ("instructions", ""),
                              ("tool_names", "")):
            values = tuple(getattr(self, name)) or (default,) * n
            if len(values) != n:
                raise ValueError(f"{name} has {len(values)} entries for {n} poses")
            object.__setattr__(self, name, values)
        object.__setattr__(self, "tools", MappingProxyType(dict(self.tools)))

    def __len__(self) -> int:
        return len(self.positions_mm)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TaughtPath):
            return NotImplemented
        return (
            np.array_equal(self.positions_mm, other.positions_mm)
            and np.array_equal(self.quaternions_wxyz, other.quaternions_wxyz)
            and (self.names, self.lines, self.source, self.instructions, self.tool_names,
                 dict(self.tools), self.notes)
            == (other.names, other.lines, other.source, other.instructions, other.tool_names,
                dict(other.tools), other.notes)
        )

    __hash__ = None  # type: ignore[assignment]
