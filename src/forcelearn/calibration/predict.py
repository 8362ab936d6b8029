"""What the sensor will read at an orientation, predicted before the robot turns there.

A static tool's reading is linear in gravity in the flange frame,
``g_f = R_f^T (0, 0, -g)``, whatever the tool and the sensor's mounting::

    w(R_f) = w0 + K g_f        w0: the bias in the present offset state (6,)
                               K (6x3): [m R_m^T ; m [c]x R_m^T], the tool's weight and moment

so four orientations whose gravity directions are not coplanar determine it,
with no assumption about mass, centre of mass or mounting. :class:`ReadingModel`
fits it by least squares on the poses measured so far and predicts each
orientation with its standard uncertainty; :func:`out_of_range` names the axes
whose predicted reading (zeroed, or the tool's weight alone: what a sensor that
saturates before its software bias sees) would pass a fraction of the full scale.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from forcelearn.calibration.model import AXES, STANDARD_GRAVITY_M_S2, Quaternion
from forcelearn.devices import quaternion_to_matrix

MAX_MODEL_CONDITION = 1.0e4
"""Largest condition number of the [g_f, 1] rows for the model to count as determined."""
SIGMAS = 4.0
"""Predicted readings are checked at their value plus this many standard uncertainties."""
RANGE_FRACTION = 0.9
"""Largest predicted reading, as a fraction of the axis's full scale (the sensor's
calibrated range; a JR3 counts further, a Net F/T clips at its range)."""


def flange_gravity(q: Quaternion) -> np.ndarray:
    """Gravity in the flange frame (3,), m/s^2, for the robot's orientation ``q``."""
    g: np.ndarray = quaternion_to_matrix(q).T @ np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2])
    return g


@dataclass
class ReadingModel:
    """w = w0 + K g_f, fitted on the poses measured so far (mean readings, their noise)."""

    noise_std: np.ndarray
    """Per-sample noise std per axis (N, N*m)."""
    rows: list[np.ndarray] = field(default_factory=list)
    means: list[np.ndarray] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)

    def add(self, q: Quaternion, mean: np.ndarray, samples: int) -> None:
        """Note a measured pose: the robot's orientation, its mean reading, its sample count."""
        self.rows.append(np.append(flange_gravity(q) / STANDARD_GRAVITY_M_S2, 1.0))
        self.means.append(np.asarray(mean, dtype=float))
        self.counts.append(max(int(samples), 1))

    @property
    def determined(self) -> bool:
        """True once the measured gravity directions are not coplanar (four or more)."""
        if len(self.rows) < 4:
            return False
        s = np.linalg.svd(np.array(self.rows), compute_uv=False)
        return bool(s[-1] > 0 and s[0] / s[-1] <= MAX_MODEL_CONDITION)

    def predict(self, q: Quaternion) -> tuple[np.ndarray, np.ndarray]:
        """Predicted zeroed reading (6,) and its standard uncertainty (6,) at ``q``.

        Each axis is its own weighted least squares (weights: samples per pose);
        the uncertainty is the noise of the means propagated, inflated by the
        fit's residual when that is larger (a bias drifting between poses).
        """
        a = np.array(self.rows)
        y = np.array(self.means)
        w = np.sqrt(np.array(self.counts, dtype=float))
        aw = a * w[:, None]
        coef, *_ = np.linalg.lstsq(aw, y * w[:, None], rcond=None)
        x = np.append(flange_gravity(q) / STANDARD_GRAVITY_M_S2, 1.0)
        inv = np.linalg.pinv(aw.T @ aw)
        spread = float(np.sqrt(max(x @ inv @ x, 0.0)))
        scale = np.asarray(self.noise_std, dtype=float)
        dof = len(a) - 4
        if dof > 0:
            residual = (y - a @ coef) * w[:, None]
            scale = np.maximum(scale, np.sqrt(np.sum(residual**2, axis=0) / dof))
        predicted: np.ndarray = x @ coef
        return predicted, scale * spread

    def weight_alone(self, q: Quaternion) -> np.ndarray:
        """The tool's load alone, K g_f (6,): the reading less any bias or offset."""
        a = np.array(self.rows)
        w = np.sqrt(np.array(self.counts, dtype=float))
        coef, *_ = np.linalg.lstsq(a * w[:, None], np.array(self.means) * w[:, None], rcond=None)
        load: np.ndarray = (flange_gravity(q) / STANDARD_GRAVITY_M_S2) @ coef[:3]
        return load


def out_of_range(model: ReadingModel, q: Quaternion, full_scales: np.ndarray,
                 fraction: float = RANGE_FRACTION) -> list[str]:
    """Axes whose predicted reading at ``q`` passes ``fraction`` of the full scale, described."""
    predicted, std = model.predict(q)
    weight = model.weight_alone(q)
    limits = fraction * np.asarray(full_scales, dtype=float)
    found = []
    for i, axis in enumerate(AXES):
        worst = max(abs(predicted[i]) + SIGMAS * std[i], abs(weight[i]) + SIGMAS * std[i])
        if limits[i] > 0 and worst > limits[i]:
            unit = "N" if i < 3 else "N*m"
            found.append(f"{axis} {predicted[i]:.3g} ± {std[i]:.2g} {unit} (tool load alone "
                         f"{weight[i]:.3g}) against {fraction:g} x full scale = "
                         f"{limits[i]:g} {unit}")
    return found
