"""Paper §4's contour task for ``B`` arms at once (the batched simulation of studies).

The same evaluation, failure rule and velocity definition as
:class:`forcelearn.tasks.contour.ContourTask`, over arrays: arm ``b`` gives the
same numbers, bit for bit, as a single task on a single cell. The polar angle
uses ``math.atan2`` per arm, since numpy's ``arctan2`` may differ from it in
the last bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from forcelearn.tasks.contour import (
    ContourGeometryLike,
    ContourTaskSpec,
    IncrementalJointOutput,
)


class ContourCells(Protocol):
    """What the batched task needs of ``B`` two-link cells (``TwoLinkContourCells``)."""

    size: int

    @property
    def geometry(self) -> ContourGeometryLike:
        """The surface all the cells' arms press on (read only)."""
        ...

    def reset(self, arms: np.ndarray) -> np.ndarray:
        """Return ``arms`` to the start pose; return (M, 2) joint angles, deg."""
        ...

    def move(self, arms: np.ndarray, command_deg: np.ndarray) -> np.ndarray:
        """Apply (M, 2) joint commands, deg; return the reached angles."""
        ...

    def tip_m(self, arms: np.ndarray) -> np.ndarray:
        """Return the (M, 2) tool tips, m."""
        ...

    def force_n(self, tip_m: np.ndarray) -> np.ndarray:
        """Return the (M,) normal forces, N, at the given tips."""
        ...


@dataclass(frozen=True)
class BatchOutcome:
    """What ``M`` arms report after one control step (arrays over those arms)."""

    x: np.ndarray
    """Next inputs (θ1, θ2), (M, 2), deg."""
    r: np.ndarray
    """Evaluations, (M,); > 1 fails."""
    failed: np.ndarray
    """True ends that arm's trial, (M,)."""
    force_n: np.ndarray
    """Normal force after the step, (M,), N."""
    force_error_n: np.ndarray
    """Measured minus desired force, (M,), N."""


class BatchedContourTask:
    """The §4 episodic task over ``B`` cells; calls name the arms (``members``) they touch."""

    name = "contour"

    def __init__(self, cells: ContourCells, spec: ContourTaskSpec | None = None):
        self.cells = cells
        self.spec = spec or ContourTaskSpec()
        self.steps_per_trial = self.spec.steps_per_trial
        self.desired_force_n = self.spec.desired_force_n
        self.grid = self.spec.grid()
        geometry = cells.geometry
        self._centre = geometry.centre_m
        self._track_radius_m = geometry.radius_m - self.desired_force_n / geometry.stiffness_n_per_m
        self._angle = np.zeros(cells.size)
        self.start_force_n = np.full(cells.size, math.nan)
        dims = self.grid.dimensions
        self._lows = np.array([d.low for d in dims])
        self._highs = np.array([d.high for d in dims])

    def output_map(self) -> IncrementalJointOutput:
        """The output function y (it works on (M, 2) arrays as it is)."""
        return IncrementalJointOutput(self.spec.output_scale_deg, self.spec.max_step_deg)

    def reset(self, members: np.ndarray) -> np.ndarray:
        """Return the arms to the start pose; return their (M, 2) joint angles, deg."""
        theta = self.cells.reset(members)
        tip = self.cells.tip_m(members)
        self._angle[members] = self._polar_angle(tip)
        self.start_force_n[members] = self.cells.force_n(tip)
        return theta

    def step(self, members: np.ndarray, command: np.ndarray) -> BatchOutcome:
        """Send (M, 2) joint commands, deg; evaluate force and surface progress."""
        theta = self.cells.move(members, command)
        tip = self.cells.tip_m(members)
        force = self.cells.force_n(tip)
        angle = self._polar_angle(tip)
        turned = np.remainder(angle - self._angle[members] + math.pi, 2.0 * math.pi) - math.pi
        velocity_m = turned * self._track_radius_m
        self._angle[members] = angle
        force_error = force - self.desired_force_n
        velocity_error = velocity_m - self.spec.desired_velocity_m
        r = (
            np.abs(force_error) / self.spec.force_scale_n
            + np.abs(velocity_error) / self.spec.velocity_scale_m
        )
        inside = ((self._lows <= theta) & (theta <= self._highs)).all(axis=1)
        return BatchOutcome(theta, r, (r > 1.0) | ~inside, force, force_error)

    def _polar_angle(self, tip: np.ndarray) -> np.ndarray:
        cx, cy = self._centre
        return np.array([math.atan2(y - cy, x - cx) for x, y in tip.tolist()])
