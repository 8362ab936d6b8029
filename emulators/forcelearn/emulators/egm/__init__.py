"""Emulated ABB controller running EGM pose guidance (the controller side of the UDP link).

* ``servo``: dead time + first-order lag motion model, with a seam for the shared one (pure).
* ``controller``: the EGM state of the controller: sessions, CommTimeout, states (pure).
* ``faults``: fault-injection hook (lost, duplicated, reordered, late, restart).
* ``shared_motion``: :class:`PhysicsMotion`, the seam filled by the cell's shared arm.
* ``cycles``: :class:`CycleLoop`, the cycle grid as two halves (pure), run by both routes.
* ``base``: :class:`EgmEmulatorBase`, what both routes share (model, faults, checkpoint).
* ``server``: :class:`EgmControllerEmulator`, the running emulator on 127.0.0.1 UDP.
* ``in_process``: :class:`InProcessEgmController`, the same in the driver's thread (no UDP).

:func:`start_emulated_egm` is the one-call factory for the emulated cell.
"""

from __future__ import annotations

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.base import EgmEmulatorBase
from forcelearn.emulators.egm.controller import EgmControllerConfig, EgmControllerModel
from forcelearn.emulators.egm.faults import EgmFaultConfig
from forcelearn.emulators.egm.in_process import InProcessEgmController
from forcelearn.emulators.egm.server import EgmControllerEmulator
from forcelearn.emulators.egm.servo import LagServo, MotionModel, ServoParams
from forcelearn.emulators.egm.shared_motion import PhysicsMotion, egm_motion_params
from forcelearn.emulators.faults import Fault
from forcelearn.emulators.physics.cell import CellPhysics

__all__ = [
    "EgmControllerConfig",
    "EgmControllerEmulator",
    "EgmControllerModel",
    "EgmEmulatorBase",
    "EgmFaultConfig",
    "Fault",
    "InProcessEgmController",
    "LagServo",
    "MotionModel",
    "PhysicsMotion",
    "ServoParams",
    "egm_motion_params",
    "start_emulated_egm",
]


def start_emulated_egm(
    physics: CellPhysics,
    clock: SimClock,
    remote_port: int,
    config: EgmControllerConfig | None = None,
    faults: EgmFaultConfig | None = None,
    motion: MotionModel | None = None,
) -> EgmControllerEmulator:
    """Start an emulated EGM controller for an emulated cell (lockstep) and return it.

    ``remote_port`` is the driver's bound port (``EgmRobot.port``); the
    driver must be configured with ``lockstep = True``. ``motion`` replaces the
    private servo (the emulated cell passes :class:`PhysicsMotion` over the shared
    arm). Stop it with ``stop()``.
    """
    emulator = EgmControllerEmulator(
        remote_port,
        physics=physics,
        clock=clock,
        config=config,
        faults=faults,
        lockstep=True,
        motion=motion,
    )
    emulator.start()
    return emulator
