"""``forcelearn check``'s compensated wrench: the calibration seen to hold before any contact.

With a calibration in force (``[calibration] file``), :func:`report_compensation`
reads free-space samples at the orientation the robot is in and prints their
compensated mean and spread per axis; with ``--turn`` it also turns the tool,
about the tool point, 30 deg about world +x, +y, -x and -y (in 10 deg steps,
a sample read after each so the force limit watches) and back. At each
orientation turned from the zero it says whether the calibrated tool still
fits: every compensated axis within 3 sigma of the calibration's noise
(:func:`~forcelearn.calibration.tool_check.check_free_space`); otherwise the
check fails with :class:`~forcelearn.errors.ToolMismatch` pointing to
``forcelearn calibrate``. Without ``--turn`` the robot is not moved.
"""

from __future__ import annotations

import numpy as np

from forcelearn.calibration import AXES
from forcelearn.calibration.model import Quaternion
from forcelearn.calibration.tool_check import check_free_space
from forcelearn.devices import Pose
from forcelearn.errors import ToolMismatch
from forcelearn.site import CellSession
from forcelearn.site.emulated_tool import mounting_rpy_deg
from forcelearn.site.kinds import Printer
from forcelearn.tools.commands.calibrate_guard import turned
from forcelearn.tools.experiments.calibration_plan import slerp_steps

TURNS = (("+x", (1.0, 0.0, 0.0)), ("+y", (0.0, 1.0, 0.0)), ("-x", (-1.0, 0.0, 0.0)),
         ("-y", (0.0, -1.0, 0.0)))
TURN_DEG = 30.0
"""Tilt of each checked orientation from the present one, deg."""
STEP_DEG = 10.0
"""Largest turn per move command, deg."""
SAMPLES = 200
"""Samples averaged at each orientation."""


def report_compensation(session: CellSession, say: Printer, turn: bool = False) -> None:
    """Print the compensated free-space wrench at the present orientation (and turned ones).

    Raises ToolMismatch (robot stopped) when a turned orientation disagrees
    with the calibrated tool; device errors as the cell raises them.
    """
    cell, cal = session.cell, session.calibration
    if cell is None or session.sensor is None:
        raise ValueError("report_compensation needs an open CellSession")
    if cal is None:
        say("  tool    no [calibration] file: readings are not compensated for bias and tool "
            "weight (run `forcelearn calibrate`)")
        return
    t = cal.tool
    say(f"  tool    calibrated {t.mass_kg:.4f} ± {t.mass_std_kg:.4f} kg, centre of mass "
        f"{[round(c, 2) for c in t.com_mm]} mm, mounting roll-pitch-yaw "
        f"{[round(a, 2) for a in mounting_rpy_deg(t.mounting_quaternion)]} deg "
        f"({t.mounting_source})")
    say(f"  tool    compensated free-space wrench, mean ± std of {SAMPLES} samples "
        f"(N, N·m; 3 sigma of the noise: {np.round(3 * cal.noise.std, 3).tolist()}):")
    start = cell.read_pose()
    orientations: list[tuple[str, Quaternion]] = [("as it is", start.quaternion)]
    if turn:
        orientations += [(f"tilted {TURN_DEG:g} deg about world {name}",
                          turned(start.quaternion, axis, TURN_DEG)) for name, axis in TURNS]
    here = start.quaternion
    for name, q in orientations:
        here = _turn(session, start, here, q)
        _report_here(session, say, name)
    if turn:
        _turn(session, start, here, start.quaternion)


def _turn(session: CellSession, start: Pose, here: Quaternion, target: Quaternion) -> Quaternion:
    """Turn about the tool point in steps of STEP_DEG, a sample read after each."""
    cell = session.cell
    assert cell is not None
    steps = slerp_steps(here, target, STEP_DEG) if here != target else []
    for step in steps:
        cell.move_to(Pose(start.x_mm, start.y_mm, start.z_mm, step))
        cell.measure_force_n(1)
    return target


def _report_here(session: CellSession, say: Printer, name: str) -> None:
    cell, cal = session.cell, session.calibration
    assert cell is not None and cal is not None and cell.compensation is not None
    reached = cell.reached_pose()
    wrenches = np.array([cell.compensation(session.sensor.read().wrench, reached)
                         for _ in range(SAMPLES)])
    mean, std = wrenches.mean(axis=0), wrenches.std(axis=0)
    cells = "  ".join(f"{a} {m:+.3f}±{s:.3f}" for a, m, s in zip(AXES, mean, std, strict=True))
    try:
        fits = check_free_space(cal, mean, reached.quaternion, cal.zero_quaternion)
    except ToolMismatch:
        say(f"  tool    {name:<28} {cells}  DOES NOT FIT")
        cell.stop()
        raise
    verdict = "fits (within 3 sigma)" if fits else "at the zero's orientation"
    say(f"  tool    {name:<28} {cells}  {verdict}")
