"""Does the calibrated tool still fit? Free-space readings at a new orientation against it.

After a zero at one orientation the compensated free-space reading is zero
there whatever the tool; only at another orientation does a wrong tool show:
the weight and moment it leaves uncompensated change with the turn. So
:func:`check_free_space` compares the compensated mean reading, in free space,
at an orientation turned at least ``MIN_TURN_DEG`` from the zero's, with
``SIGMAS`` (3) standard deviations per axis: the calibration's noise, and its
own uncertainty over that turn (:func:`model_std`; without it a heavy tool on
a sensor of small noise would not fit its own calibration).
Beyond it: :class:`~forcelearn.errors.ToolMismatch`, pointing to
``forcelearn calibrate``.
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.calibration.model import (
    AXES,
    MM_PER_M,
    STANDARD_GRAVITY_M_S2,
    Calibration,
    Quaternion,
    gravity_in_sensor,
)
from forcelearn.errors import ToolMismatch

SIGMAS = 3.0
"""A compensated free-space axis beyond this many noise standard deviations disagrees."""
MIN_TURN_DEG = 5.0
"""Gravity must have turned this much (deg) from the zero's orientation to tell anything."""


def turn_deg(a: Quaternion, b: Quaternion) -> float:
    """Angle (deg) between gravity's directions in the flange frame at orientations a and b."""
    ga, gb = gravity_in_sensor(a), gravity_in_sensor(b)
    cos = float(ga @ gb / (np.linalg.norm(ga) * np.linalg.norm(gb)))
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def model_std(cal: Calibration, turn: float) -> np.ndarray:
    """The calibration's own uncertainty (6,) of the weight change over a turn of ``turn`` deg.

    The compensation at a turned orientation subtracts W(q) - W(q_zero); its
    error from the fit's m and c grows as 2 sin(turn / 2): g * std(m) on the
    forces, g * sqrt((m std(c))^2 + (|c| std(m))^2) on the moments (N, N*m).
    """
    t = cal.tool
    chord = 2.0 * math.sin(math.radians(turn) / 2.0)
    force = STANDARD_GRAVITY_M_S2 * t.mass_std_kg
    moment = STANDARD_GRAVITY_M_S2 * math.hypot(
        t.mass_kg * float(np.linalg.norm(t.com_std_mm)),
        float(np.linalg.norm(t.com_mm)) * t.mass_std_kg) / MM_PER_M
    return chord * np.array([force] * 3 + [moment] * 3)


def check_free_space(cal: Calibration, compensated_mean: np.ndarray, quaternion: Quaternion,
                     zero_quaternion: Quaternion, source: str = "the calibration") -> bool:
    """Raise ToolMismatch if the compensated free-space mean passes SIGMAS noise std.

    Returns False when the orientation is too close to the zero's to tell, True
    when the tool fits.
    """
    turn = turn_deg(quaternion, zero_quaternion)
    if turn < MIN_TURN_DEG:
        return False
    std = np.hypot(cal.noise.std, model_std(cal, turn))
    mean = np.asarray(compensated_mean, dtype=float)
    beyond = [i for i in range(6) if abs(mean[i]) > SIGMAS * std[i]]
    if not beyond:
        return True
    axes = ", ".join(f"{AXES[i]} {mean[i]:+.3g} ({SIGMAS:g} sigma = {SIGMAS * std[i]:.3g})"
                     for i in beyond)
    raise ToolMismatch(
        f"the tool does not fit {source}: in free space, {turn:.0f} deg from the orientation of "
        f"the zero, the compensated reading is {axes} (N, N*m), beyond {SIGMAS:g} sigma of the "
        f"noise: the tool was changed, or the calibration is of another tool "
        f"({cal.tool.mass_kg:.3f} kg, centre of mass {[round(c, 1) for c in cal.tool.com_mm]} "
        "mm); with nothing touching the tool, run `forcelearn calibrate`"
    )
