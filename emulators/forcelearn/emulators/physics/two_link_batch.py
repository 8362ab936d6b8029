"""``B`` copies of the §4 two-link cell stepped together (numpy over arms).

Same physics, same geometry and the same floating-point operations as
:class:`~forcelearn.emulators.physics.two_link_arm.TwoLinkContourCell`, so arm
``b`` of a batch reaches the same angles and forces, bit for bit, as a single
cell given the same commands. ``math.hypot`` is applied per arm (numpy's
``hypot`` may differ from it in the last bit); ``cos``/``sin`` are numpy's,
which equal libm's on the machines tested (tests/emulators/test_two_link_batch.py).

| array | shape | unit |
|---|---|---|
| ``theta_deg`` | (B, 2) | deg |
| tip | (M, 2) | m |
| force | (M,) | N |
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.emulators.physics.two_link_arm import ContourGeometry


class TwoLinkContourCells:
    """``size`` independent two-link cells on one geometry; calls name the arms they touch."""

    def __init__(self, geometry: ContourGeometry | None, size: int):
        self.geometry = geometry or ContourGeometry()
        self.size = int(size)
        self.theta_deg = np.tile(np.array(self.geometry.start_theta_deg, dtype=float), (size, 1))

    def reset(self, arms: np.ndarray) -> np.ndarray:
        """Return ``arms`` to the start pose; return their joint angles (M, 2), deg."""
        self.theta_deg[arms] = self.geometry.start_theta_deg
        theta: np.ndarray = self.theta_deg[arms].copy()
        return theta

    def move(self, arms: np.ndarray, command_deg: np.ndarray) -> np.ndarray:
        """Apply joint commands (M, 2) deg through the servo; return the reached angles."""
        keep = self.geometry.servo_lag
        theta = self.theta_deg[arms]
        reached: np.ndarray = command_deg + keep * (theta - command_deg)
        self.theta_deg[arms] = reached
        return reached

    def tip_m(self, arms: np.ndarray) -> np.ndarray:
        """Return the tool tips (M, 2) in m."""
        g = self.geometry
        theta = self.theta_deg[arms]
        t1 = np.radians(theta[:, 0])
        t12 = t1 + np.radians(theta[:, 1])
        tip = np.empty((theta.shape[0], 2))
        tip[:, 0] = g.link1_m * np.cos(t1) + g.link2_m * np.cos(t12)
        tip[:, 1] = g.link1_m * np.sin(t1) + g.link2_m * np.sin(t12)
        return tip

    def force_n(self, tip_m: np.ndarray) -> np.ndarray:
        """Return the normal force (M,) in N on tips (M, 2) m (zero out of contact)."""
        g = self.geometry
        cx, cy = g.centre_m
        distance = [math.hypot(x - cx, y - cy) for x, y in tip_m.tolist()]
        penetration = g.radius_m - np.array(distance)
        return np.where(penetration > 0.0, g.stiffness_n_per_m * penetration, 0.0)
