"""Old device names stay importable for one release: each warns and gives the new object."""

from __future__ import annotations

import importlib
import sys

import pytest

RENAMED = [
    ("forcelearn.emulators.robot_controller", "RobotControllerEmulator",
     "forcelearn.emulators.computer_link", "ComputerLinkEmulator"),
    ("forcelearn.emulators.robot_controller", "FaultConfig",
     "forcelearn.emulators.computer_link", "ComputerLinkFaultConfig"),
    ("forcelearn.emulators.computer_link.server", "RobotControllerEmulator",
     "forcelearn.emulators.computer_link", "ComputerLinkEmulator"),
    ("forcelearn.emulators.computer_link.faults", "FaultConfig",
     "forcelearn.emulators.computer_link", "ComputerLinkFaultConfig"),
    ("forcelearn.emulators.jr3", "FaultConfig", "forcelearn.emulators.jr3", "Jr3FaultConfig"),
    ("forcelearn.emulators.jr3.faults", "FaultConfig", "forcelearn.emulators.jr3",
     "Jr3FaultConfig"),
    ("forcelearn.emulators.jr3", "SensorModel", "forcelearn.emulators.jr3", "Jr3SensorModel"),
    ("forcelearn.emulators.jr3", "SensorModelParams", "forcelearn.emulators.jr3",
     "Jr3ModelParams"),
    ("forcelearn.emulators.jr3.sensor_model", "SensorModelParams", "forcelearn.emulators.jr3",
     "Jr3ModelParams"),
    ("forcelearn.drivers.egm", "EgmRobotDriver", "forcelearn.drivers.egm", "EgmRobot"),
    ("forcelearn.drivers.egm.driver", "EgmRobotDriver", "forcelearn.drivers.egm", "EgmRobot"),
]


@pytest.mark.parametrize(("module", "old", "new_module", "new"), RENAMED,
                         ids=[f"{m}.{o}" for m, o, _, _ in RENAMED])
def test_an_old_name_warns_and_is_the_new_object(module: str, old: str, new_module: str,
                                                 new: str) -> None:
    """Reading the old name gives a DeprecationWarning naming the new one, and the new object."""
    with pytest.warns(DeprecationWarning, match=new):
        found = getattr(importlib.import_module(module), old)
    assert found is getattr(importlib.import_module(new_module), new)


def test_an_unknown_name_is_still_an_attribute_error() -> None:
    """The alias hook answers only the old names."""
    with pytest.raises(AttributeError, match="NoSuchThing"):
        importlib.import_module("forcelearn.emulators.computer_link.server").NoSuchThing  # noqa: B018


def test_the_old_emulator_package_warns_and_its_modules_are_the_new_ones(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``forcelearn.emulators.robot_controller`` and its submodules import, with a warning."""
    for name in [n for n in sys.modules if n.startswith("forcelearn.emulators.robot_controller")]:
        monkeypatch.delitem(sys.modules, name)
    with pytest.warns(DeprecationWarning, match="forcelearn.emulators.computer_link"):
        server = importlib.import_module("forcelearn.emulators.robot_controller.server")
    assert server is importlib.import_module("forcelearn.emulators.computer_link.server")
    kinematics = importlib.import_module("forcelearn.emulators.robot_controller.kinematics")
    assert kinematics is importlib.import_module("forcelearn.emulators.physics.arm")


def test_the_jr3_driver_package_exports_its_sensor_and_config() -> None:
    """``forcelearn.drivers.jr3_can`` names its driver as the other driver packages do."""
    jr3_can = importlib.import_module("forcelearn.drivers.jr3_can")
    assert {"Jr3CanSensor", "Jr3Config"} <= set(jr3_can.__all__)
    assert jr3_can.Jr3CanSensor is importlib.import_module(
        "forcelearn.drivers.jr3_can.driver").Jr3CanSensor
