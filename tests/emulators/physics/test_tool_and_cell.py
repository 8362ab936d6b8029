"""Tool gravity and contact moments in the sensor frame, through the shared cell physics."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge, surface_y_mm
from forcelearn.emulators.physics.tool import STANDARD_GRAVITY_M_S2, ToolParams

TOOL = ToolParams(mass_kg=1.0, com_mm=(0.0, 0.0, 100.0), contact_point_mm=(0.0, 0.0, 200.0))
ABOUT_X_90 = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)


def test_gravity_hangs_along_minus_z_when_upright() -> None:
    """Identity orientation: weight -m g on z, no moment (centre of mass on the z axis)."""
    wrench = CellPhysics(tool=TOOL).true_wrench()
    assert wrench == pytest.approx([0, 0, -STANDARD_GRAVITY_M_S2, 0, 0, 0])


def test_gravity_rotates_with_the_flange_and_makes_a_moment() -> None:
    """Turned 90 deg about x, the weight lies along sensor -y and c x F gives a moment about x."""
    wrench = CellPhysics(tool=TOOL, pose=Pose(0, 0, 0, ABOUT_X_90)).true_wrench()
    g = STANDARD_GRAVITY_M_S2
    assert wrench == pytest.approx([0, -g, 0, 0.1 * g, 0, 0], abs=1e-9)


def test_contact_force_acts_at_the_contact_point() -> None:
    """Pressing the sponge with an upright tool: Fy > 0 and Mx = -0.2 m * Fy (p x F)."""
    sponge = Sponge()
    y = surface_y_mm(sponge.params, 0, -40.0) - 5.0
    cell = CellPhysics(sponge, Pose(0.0, y, -40.0), tool=ToolParams(mass_kg=0.0,
                       contact_point_mm=(0.0, 0.0, 200.0)))
    fx, fy, _fz, mx, my, mz = cell.true_wrench()
    assert fy > 5.0
    assert mx == pytest.approx(-0.2 * fy)
    assert (fx, my, mz) == (0.0, 0.0, 0.0)


def test_default_cell_is_a_point_tool() -> None:
    """Without a tool the wrench is the contact force only (backward compatible)."""
    assert not CellPhysics().true_wrench().any()
