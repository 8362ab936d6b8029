"""Paper §4: contour force tracking with a two-link arm on a circular surface.

Inputs are the measured joint angles (θ1, θ2) in degrees; the two outputs are
the joint angle commands. The evaluation is eq. (4)::

    r = |force error| / 2 N + |velocity error| / 2 cm

with desired force 1 N and desired velocity 1 cm per step along the surface.
A step with r > 1, or one that leaves the partitioned joint ranges, is a
failure: the trial ends and the arm returns to the start pose. The path is
complete after 45 steps.

Choices the paper leaves open (docs/contour.md gives the reasons):

* velocity = progress along the surface per step: the change of the tip's
  polar angle about the disc centre times the radius of the 1 N contour
  (signed, so moving backwards is an error of more than 1 cm);
* output y(a, θ) = θ + a · ``output_scale_deg`` (a joint-angle increment over
  the measured angles), clipped to ±``max_step_deg`` per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from forcelearn.errors import ConfigError
from forcelearn.learning import BoxGrid, Dimension
from forcelearn.trainer import StepOutcome


@dataclass(frozen=True)
class ContourTaskSpec:
    """The task's targets, partition and output map (paper §4 values as defaults)."""

    desired_force_n: float = 1.0
    desired_velocity_m: float = 0.01
    """Desired progress along the surface per step, m (1 cm/step)."""
    force_scale_n: float = 2.0
    """Divisor of the force error in eq. (4), N."""
    velocity_scale_m: float = 0.02
    """Divisor of the velocity error in eq. (4), m."""
    steps_per_trial: int = 45
    theta1_range_deg: tuple[float, float] = (30.0, 60.0)
    theta1_parts: int = 100
    theta2_range_deg: tuple[float, float] = (-75.0, -15.0)
    theta2_parts: int = 200
    output_scale_deg: float = 0.4
    """Degrees of joint command per action unit (not in the paper; docs/contour.md)."""
    max_step_deg: float = 5.0
    """Largest joint increment one command may ask for, degrees (a safety limit)."""

    def __post_init__(self) -> None:
        for name in ("steps_per_trial", "theta1_parts", "theta2_parts"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"task.{name} = {value!r}: must be a whole number >= 1")
        positive = (
            "desired_force_n", "desired_velocity_m", "force_scale_n", "velocity_scale_m",
            "output_scale_deg", "max_step_deg",
        )
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"task.{name} = {value!r}: must be a finite number > 0")
        for name in ("theta1_range_deg", "theta2_range_deg"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ConfigError(f"task.{name} = {(lo, hi)!r}: must be (low, high), low < high")

    def check_start(self, start_theta_deg: tuple[float, float]) -> None:
        """Refuse a start pose outside the input partition (every trial would fail at once)."""
        for i, (name, theta) in enumerate(
            (("theta1_range_deg", start_theta_deg[0]), ("theta2_range_deg", start_theta_deg[1]))
        ):
            lo, hi = getattr(self, name)
            if not lo <= theta <= hi:
                raise ConfigError(
                    f"geometry.start_theta_deg[{i}] = {theta:g} deg lies outside "
                    f"task.{name} = [{lo:g}, {hi:g}]: the start must be inside the partition"
                )

    def grid(self) -> BoxGrid:
        """The BOXES partition of (θ1, θ2): 100 x 200 boxes by default."""
        return BoxGrid(
            [
                Dimension("theta1_deg", *self.theta1_range_deg, self.theta1_parts),
                Dimension("theta2_deg", *self.theta2_range_deg, self.theta2_parts),
            ]
        )


class ContourCell(Protocol):
    """What the task needs of the two-link cell (the emulator's ``TwoLinkContourCell``)."""

    @property
    def geometry(self) -> ContourGeometryLike:
        """The surface the cell's arm presses on (read only)."""
        ...

    def reset(self) -> tuple[float, float]:
        """Return to the start pose; return (θ1, θ2) in degrees."""
        ...

    def move(self, theta1_cmd_deg: float, theta2_cmd_deg: float) -> tuple[float, float]:
        """Apply joint commands (deg); return the reached angles (deg)."""
        ...

    def tip_m(self) -> tuple[float, float]:
        """Return the tool tip (x, y) in m."""
        ...

    def force_n(self) -> float:
        """Return the normal contact force in N."""
        ...


class ContourGeometryLike(Protocol):
    """The surface facts the evaluation needs: centre, radius, stiffness (read only)."""

    @property
    def centre_m(self) -> tuple[float, float]:
        """Centre (x, y) of the circular surface, m."""
        ...

    @property
    def radius_m(self) -> float:
        """Radius of the surface, m."""
        ...

    @property
    def stiffness_n_per_m(self) -> float:
        """Normal stiffness of the surface, N/m."""
        ...


class IncrementalJointOutput:
    """y(a, θ) = θ + clip(a · scale, ±max_step): joint commands in degrees."""

    def __init__(self, scale_deg: float, max_step_deg: float):
        self.scale_deg = scale_deg
        self.max_step_deg = max_step_deg

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Return the joint-angle commands for action ``a`` at measured angles ``x``."""
        return x + np.clip(a * self.scale_deg, -self.max_step_deg, self.max_step_deg)


def evaluation(spec: ContourTaskSpec, force_error_n: float, velocity_error_m: float) -> float:
    """Eq. (4): r = |force error| / 2 N + |velocity error| / 2 cm (dimensionless)."""
    return abs(force_error_n) / spec.force_scale_n + abs(velocity_error_m) / spec.velocity_scale_m


class ContourTask:
    """The §4 episodic task over a two-link contour cell (anything with the cell's methods).

    Args:
        cell: the simulated arm (``reset``, ``move``, ``tip_m``, ``force_n``, ``geometry``).
        spec: targets, partition and output map.
    """

    name = "contour"

    def __init__(self, cell: ContourCell, spec: ContourTaskSpec | None = None):
        self.cell = cell
        self.spec = spec or ContourTaskSpec()
        self.steps_per_trial = self.spec.steps_per_trial
        self.desired_force_n = self.spec.desired_force_n
        self.grid = self.spec.grid()
        geometry = cell.geometry
        self._centre = geometry.centre_m
        self._track_radius_m = geometry.radius_m - self.desired_force_n / geometry.stiffness_n_per_m
        self._angle = 0.0
        self.start_force_n = math.nan

    def output_map(self) -> IncrementalJointOutput:
        """The output function y this task expects the learner to use."""
        return IncrementalJointOutput(self.spec.output_scale_deg, self.spec.max_step_deg)

    def reset(self) -> np.ndarray:
        """Return the arm to the start pose; return (θ1, θ2) in degrees."""
        theta = self.cell.reset()
        self._angle = self._polar_angle()
        self.start_force_n = self.cell.force_n()
        return np.array(theta, dtype=float)

    def step(self, command: np.ndarray) -> StepOutcome:
        """Send the joint commands (deg); evaluate force and surface progress."""
        theta = self.cell.move(float(command[0]), float(command[1]))
        force = self.cell.force_n()
        angle = self._polar_angle()
        turned = (angle - self._angle + math.pi) % (2.0 * math.pi) - math.pi  # unwrap at ±π
        velocity_m = turned * self._track_radius_m
        self._angle = angle
        force_error = force - self.desired_force_n
        velocity_error = velocity_m - self.spec.desired_velocity_m
        r = evaluation(self.spec, force_error, velocity_error)
        x = np.array(theta, dtype=float)
        failed = r > 1.0 or not self.grid.contains(x)
        tip = self.cell.tip_m()
        extras = {
            "theta1_deg": x[0],
            "theta2_deg": x[1],
            "tip_x_m": tip[0],
            "tip_y_m": tip[1],
            "velocity_error_m": velocity_error,
        }
        return StepOutcome(x, r, failed, force, force_error, extras)

    def _polar_angle(self) -> float:
        """Tip angle about the disc centre, rad in (−π, π]."""
        x, y = self.cell.tip_m()
        return math.atan2(y - self._centre[1], x - self._centre[0])
