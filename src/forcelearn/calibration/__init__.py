"""Sensor calibration: bias, noise and tool load, the fits that find them, and their file.

``forcelearn calibrate`` (:mod:`forcelearn.tools.commands.calibrate`) measures; this
package fits (:mod:`.fit`; with the sensor's mounting on the flange, given or
estimated, :mod:`.mounting`), predicts the reading before a turn
(:mod:`.predict`), holds the result (:mod:`.model`), stores it
(:mod:`.file_format`) and tells when the tool no longer fits (:mod:`.tool_check`);
:class:`~forcelearn.site.session.CellSession` loads the file, gives the Kalman
filter R from the noise variance and installs :meth:`Calibration.compensation`
on the cell. All of it is pure but the file I/O.

The tool-load model (wrench order Fx Fy Fz Mx My Mz, sensor frame, N and N*m)
----------------------------------------------------------------------------
A static tool of mass ``m`` with centre of mass ``c`` (sensor frame) held in
orientation ``R = R_f R_m`` (sensor frame -> world, world z up; ``R_f`` the
flange's, as the robot reports it, ``R_m`` the sensor's mounting) reads::

    g_s = R^T (0, 0, -g)                        gravity in the sensor frame, m/s^2
    F   = F0 + m g_s                            N
    M   = M0 + c x (m g_s) = M0 - [g_s]x (m c)  N*m

linear in the 10 parameters ``p = (m, m c, F0, M0)`` (kg, kg*m, N, N*m). Each
pose adds the 6 x 10 block ``[[g_s, 0, I, 0], [0, -[g_s]x, 0, I]]``; weighted
least squares over the poses gives ``p`` and ``s^2 (A^T A)^-1`` its covariance,
``s^2`` the residual variance. A pose set whose column-normalised design
matrix has a condition number above ``fit.MAX_CONDITION`` is refused, naming
orientations to add.

What "bias" means
-----------------
``F0, M0`` (``tool.force_bias_n``, ``tool.torque_bias_nm``) is what the sensor
reads *in its present offset state* with the tool weightless. Zeroing the
offsets stores the whole free-space reading, the sensor's own bias *and* the
tool's weight in that orientation ``R_z``, so right after zeroing
``(F0, M0) = -[m g_s(R_z); c x m g_s(R_z)]`` plus whatever the zero missed;
:meth:`Calibration.rezeroed` re-derives it after a new zero.
``noise.bias`` is another thing: the mean reading right after zeroing, at the
zeroing pose, gravity included (ideally 0). The compensation::

    compensated = measured - (F0, M0) - [m g_s ; c x (m g_s)]
"""

from forcelearn.calibration.file_format import (
    dumps,
    from_document,
    load_calibration,
    save_calibration,
    to_toml,
)
from forcelearn.calibration.fit import (
    MAX_CONDITION,
    check_matrix,
    check_pose_set,
    condition_number,
    design_matrix,
    estimate_noise,
    fit_tool_load,
    orientation_with_down,
    suggest_poses,
)
from forcelearn.calibration.model import (
    AXES,
    FORMAT_VERSION,
    MOUNTING_ESTIMATED,
    MOUNTING_GIVEN,
    STANDARD_GRAVITY_M_S2,
    TOOL_DOWN,
    Calibration,
    MatrixCheck,
    NoiseEstimate,
    PoseFit,
    SensorInfo,
    ToolLoad,
    gravity_in_sensor,
)
from forcelearn.devices import quaternion_to_matrix

__all__ = [
    "AXES",
    "FORMAT_VERSION",
    "MAX_CONDITION",
    "MOUNTING_ESTIMATED",
    "MOUNTING_GIVEN",
    "STANDARD_GRAVITY_M_S2",
    "TOOL_DOWN",
    "Calibration",
    "MatrixCheck",
    "NoiseEstimate",
    "PoseFit",
    "SensorInfo",
    "ToolLoad",
    "check_matrix",
    "check_pose_set",
    "condition_number",
    "design_matrix",
    "dumps",
    "estimate_noise",
    "fit_tool_load",
    "from_document",
    "gravity_in_sensor",
    "load_calibration",
    "orientation_with_down",
    "quaternion_to_matrix",
    "save_calibration",
    "suggest_poses",
    "to_toml",
]
