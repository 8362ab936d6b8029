"""Does the calibrated tool still fit? Free-space readings at a new orientation against it.

After a zero at one orientation the compensated free-space reading is zero
there whatever the tool; only at another orientation does a wrong tool show:
the weight and moment it leaves uncompensated change with the turn. So
:func:`check_free_space` compares the compensated mean reading, in free space,
at an orientation turned at least ``MIN_TURN_DEG`` from the zero's, with
``SIGMAS`` (3) standard deviations of the calibration's own noise, per axis.
Beyond it: :class:`~forcelearn.errors.ToolMismatch`, pointing to
``forcelearn calibrate``.
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.calibration.model import AXES, Calibration, Quaternion, gravity_in_sensor
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


def check_free_space(cal: Calibration, compensated_mean: np.ndarray, quaternion: Quaternion,
                     zero_quaternion: Quaternion, source: str = "the calibration") -> bool:
    """Raise ToolMismatch if the compensated free-space mean passes SIGMAS noise std.

    Returns False when the orientation is too close to the zero's to tell, True
    when the tool fits.
    """
    turn = turn_deg(quaternion, zero_quaternion)
    if turn < MIN_TURN_DEG:
        return False
    std = cal.noise.std
    mean = np.asarray(compensated_mean, dtype=float)
    beyond = [i for i in range(6) if abs(mean[i]) > SIGMAS * std[i]]
    if not beyond:
        return True
    axes = ", ".join(f"{AXES[i]} {mean[i]:+.3g} (3 sigma = {SIGMAS * std[i]:.3g})"
                     for i in beyond)
    raise ToolMismatch(
        f"the tool does not fit {source}: in free space, {turn:.0f} deg from the orientation of "
        f"the zero, the compensated reading is {axes} (N, N*m), beyond {SIGMAS:g} sigma of the "
        f"noise: the tool was changed, or the calibration is of another tool "
        f"({cal.tool.mass_kg:.3f} kg, centre of mass {[round(c, 1) for c in cal.tool.com_mm]} "
        "mm); with nothing touching the tool, run `forcelearn calibrate`"
    )
