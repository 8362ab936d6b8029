"""What the core needs from a cell's devices: small value types and two Protocols.

The trainer and the tasks know the robot and the force sensor only through
:class:`Robot` and :class:`ForceSensor`; the computer-link and JR3 drivers in
``forcelearn.drivers`` satisfy them, whether the far end of the wire is a real
device or an emulator. This module imports nothing else of forcelearn but its
errors, so drivers may depend on it without depending on learning.

Frames and units: world frame of the robot base, x/y/z in millimetres,
orientation as a unit quaternion (w, x, y, z). Forces in newtons, moments in
newton-metres, times in seconds (``time.monotonic`` clock).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, TypeVar, runtime_checkable

import numpy as np

IDENTITY_QUATERNION: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
TOOL_DOWN: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0)
"""Quaternion (w, x, y, z) of a tool pointing straight down: a half turn about world x."""
STANDARD_GRAVITY_M_S2 = 9.80665
"""Standard gravity g, m/s^2 (one kilogram-force is g newtons)."""


FORCE_FULL_SCALE_RANGE_N = (1.0, 40_000.0)
"""Plausible force full scales, N (assumption: JR3's catalogue spans about 50 N to 40 kN)."""
MOMENT_FULL_SCALE_RANGE_NM = (0.1, 6_000.0)
"""Plausible moment full scales, N*m (assumption; the adapter's 0xFFFF dN*m is 6553.5)."""


def check_full_scales(full_scales: object) -> np.ndarray:
    """Return six full scales (N, N, N, N*m, N*m, N*m) as floats, or raise ValueError.

    Refuses anything but six finite values inside the plausible ranges: a full
    scale of 0 (or an erased 0xFFFF) would scale every wrench to nonsense, and a
    force limit could then never trip.
    """
    try:
        fs = np.asarray(full_scales, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"full scales must be six numbers: {exc}") from None
    if fs.shape != (6,) or not np.all(np.isfinite(fs)):
        raise ValueError(f"full scales must be six finite numbers, got {fs.tolist()}")
    for axes, (low, high), unit in (
        (slice(0, 3), FORCE_FULL_SCALE_RANGE_N, "N"),
        (slice(3, 6), MOMENT_FULL_SCALE_RANGE_NM, "N*m"),
    ):
        values = fs[axes]
        if np.any(values < low) or np.any(values > high):
            raise ValueError(
                f"full scales {fs.tolist()} are implausible: forces must be "
                f"{FORCE_FULL_SCALE_RANGE_N[0]:g}..{FORCE_FULL_SCALE_RANGE_N[1]:g} N and moments "
                f"{MOMENT_FULL_SCALE_RANGE_NM[0]:g}..{MOMENT_FULL_SCALE_RANGE_NM[1]:g} N*m "
                f"(out of range in {unit})"
            )
    return fs



_Frozen = TypeVar("_Frozen")


def _filled(cls: type[_Frozen], **values: object) -> _Frozen:
    """``cls(**values)`` for a frozen dataclass without slots: its ``__dict__`` filled at once.

    The same attributes ``__init__`` sets, without a frozen ``object.__setattr__`` per field
    (for objects built on a hot path; tests hold each user to its constructor).
    """
    made = object.__new__(cls)
    made.__dict__.update(values)
    return made


@dataclass(frozen=True)
class Pose:
    """A Cartesian tool pose: position in mm, orientation as quaternion (w, x, y, z)."""

    x_mm: float
    y_mm: float
    z_mm: float
    quaternion: tuple[float, float, float, float] = IDENTITY_QUATERNION

    @property
    def position_mm(self) -> np.ndarray:
        """Position as a float array (x, y, z) in mm."""
        return np.array([self.x_mm, self.y_mm, self.z_mm], dtype=float)

    @staticmethod
    def of(x_mm: float, y_mm: float, z_mm: float, quaternion: tuple[float, float, float, float]
           ) -> Pose:
        """``Pose(x_mm, y_mm, z_mm, quaternion)``, faster.

        The object ``__init__`` makes (the same attributes), its four frozen-field
        ``object.__setattr__`` calls as one ``__dict__`` fill (:func:`_filled`): the emulated arm's
        pose of every moving 4 ms tick and the EGM ramp's planned pose of every cycle are
        built so (a hot path; a test holds it to the constructor).
        """
        return _filled(Pose, x_mm=x_mm, y_mm=y_mm, z_mm=z_mm, quaternion=quaternion)

    def moved(self, dx_mm: float = 0.0, dy_mm: float = 0.0, dz_mm: float = 0.0) -> Pose:
        """Return this pose translated by (dx, dy, dz) mm, orientation kept."""
        return Pose(self.x_mm + dx_mm, self.y_mm + dy_mm, self.z_mm + dz_mm, self.quaternion)


def quaternion_to_matrix(q: tuple[float, float, float, float]) -> np.ndarray:
    """Return the 3x3 rotation matrix (sensor/tool frame to world) of a quaternion (w, x, y, z).

    The quaternion is normalised first, so a slightly off-unit one still gives a rotation.
    """
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def multiply_quaternions(
    a: tuple[float, ...], b: tuple[float, float, float, float]
) -> tuple[float, float, float, float]:
    """Return the Hamilton product ``a * b`` of two quaternions (w, x, y, z).

    As rotations: b, then a (in the world frame).
    """
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )



def blend_poses(a: Pose, b: Pose, fraction: float) -> Pose:
    """Pose ``fraction`` of the way from ``a`` to ``b`` (``fraction`` >= 1 gives ``b``).

    Position linearly (mm), orientation by nlerp along the shorter quaternion arc.
    """
    if fraction >= 1.0:
        return b
    position = a.position_mm + fraction * (b.position_mm - a.position_mm)
    q0, q1 = np.asarray(a.quaternion), np.asarray(b.quaternion)
    if np.dot(q0, q1) < 0:
        q1 = -q1
    q = q0 + fraction * (q1 - q0)
    q = q / np.linalg.norm(q)
    x, y, z = (float(c) for c in position)
    w, qx, qy, qz = (float(c) for c in q)
    return Pose(x, y, z, (w, qx, qy, qz))


AXES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
"""Names of a wrench's six components, in :attr:`WrenchSample.wrench` order."""


@dataclass(frozen=True)
class WrenchSample:
    """One paired force/moment sample from a 6-axis sensor.

    ``wrench`` is (Fx, Fy, Fz, Mx, My, Mz) in N and N·m, sensor frame;
    ``timestamp_s`` is the host's monotonic receive time; ``counter`` is the
    sensor's frame counter; ``saturated`` flags axes near full scale;
    ``sensor_dt_s`` is the sensor's own time since the previous sample of the
    stream, s, when the device tells it (a JR3 adapter: counter steps x its
    frame period), None when it does not or for the first sample after a start.
    """

    wrench: np.ndarray
    timestamp_s: float
    counter: int
    saturated: tuple[bool, ...] = field(default=(False,) * 6)
    sensor_dt_s: float | None = None

    @staticmethod
    def of(wrench: np.ndarray, timestamp_s: float, counter: int, saturated: tuple[bool, ...],
           sensor_dt_s: float | None) -> WrenchSample:
        """``WrenchSample(wrench, timestamp_s, counter, saturated, sensor_dt_s)``, faster.

        The object ``__init__`` makes (the same attributes), its five frozen-field
        ``object.__setattr__`` calls as one ``__dict__`` fill (:func:`_filled`): every sample of
        every burst is built once by the driver and once by the compensation (a hot path;
        a test holds it to the constructor).
        """
        return _filled(WrenchSample, wrench=wrench, timestamp_s=timestamp_s, counter=counter,
                       saturated=saturated, sensor_dt_s=sensor_dt_s)

    def with_wrench(self, wrench: np.ndarray) -> WrenchSample:
        """This sample with another wrench (time, counter and flags kept).

        ``dataclasses.replace(self, wrench=wrench)`` without its field lookup (a hot
        path: every sample of a burst is compensated); a test holds it to ``replace``.
        """
        fields = self.__dict__
        return WrenchSample.of(wrench, fields["timestamp_s"], fields["counter"],
                               fields["saturated"], fields["sensor_dt_s"])

    @property
    def force_n(self) -> np.ndarray:
        """The force part (Fx, Fy, Fz) in N."""
        return self.wrench[:3]

    @property
    def moment_nm(self) -> np.ndarray:
        """The moment part (Mx, My, Mz) in N·m."""
        return self.wrench[3:]


@dataclass(frozen=True)
class InPositionWait:
    """How a robot driver's last ``wait_in_position`` ended (read by the cell's records).

    Attributes:
        in_position_s: the robot's clock when it was first in position in that wait
            (the settle dwell began), s.
        reached: the pose the robot reported at the end of the wait; None when the
            link tells it only through another exchange (the computer link).
    """

    in_position_s: float
    reached: Pose | None


@runtime_checkable
class Robot(Protocol):
    """A position-controlled robot reached through a driver."""

    def read_pose(self) -> Pose:
        """Return the pose the robot is at now."""
        ...

    def move_to(self, pose: Pose) -> None:
        """Move to an absolute pose and return when the controller has accepted it."""
        ...

    def read_target(self) -> Pose:
        """Return the target the controller is moving to (the reference for relative moves)."""
        ...

    def wait_in_position(self, timeout_s: float, settle_s: float = 0.0) -> float:
        """Wait until the robot reports in position and has settled; return the robot's time (s).

        Raises ``NotInPosition`` (robot stopped) when ``timeout_s`` of the robot's time passes.
        """
        ...

    def stop(self) -> None:
        """Stop all motion at once; safe to call at any time."""
        ...

    def close(self) -> None:
        """Stop the robot and release the link; safe to call twice."""
        ...


@runtime_checkable
class BatchForceSensor(Protocol):
    """A force sensor that can read several consecutive samples in one exchange."""

    def read_many(self, count: int, window: int) -> list[WrenchSample]:
        """Return ``count`` consecutive fresh samples, up to ``window`` requested at once."""
        ...


@runtime_checkable
class RebootableSensor(Protocol):
    """A sensor that reports a reboot (``SensorRebooted``) instead of zeroing on its own."""

    def reinitialise(self) -> None:
        """Initialise again after a reboot, without zeroing: the caller zeroes in free space."""
        ...


@runtime_checkable
class ForceSensor(Protocol):
    """A 6-axis force/torque sensor reached through a driver."""

    def read(self) -> WrenchSample:
        """Return the next fresh sample (raises ``SensorStale`` if none arrives in time)."""
        ...

    def zero_offsets(self) -> None:
        """Store the present reading as the sensor's offset."""
        ...

    def close(self) -> None:
        """Stop streaming and release the bus; safe to call twice."""
        ...
