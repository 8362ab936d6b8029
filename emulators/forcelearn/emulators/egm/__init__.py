"""Emulated ABB controller running EGM pose guidance (the controller side of the UDP link).

* ``servo``: dead time + first-order lag motion model, with a seam for the shared one (pure).
* ``controller``: the EGM state of the controller: sessions, CommTimeout, states (pure).
* ``faults``: fault-injection hook (lost, duplicated, reordered, late, restart).
* ``server``: :class:`EgmControllerEmulator`, the running emulator on 127.0.0.1 UDP.

:func:`start_emulated_egm` is the one-call factory for the emulated cell.
"""

from __future__ import annotations

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.controller import EgmControllerConfig, EgmControllerModel
from forcelearn.emulators.egm.faults import EgmFaultConfig, Fault
from forcelearn.emulators.egm.server import EgmControllerEmulator
from forcelearn.emulators.egm.servo import LagServo, ServoParams
from forcelearn.emulators.physics.cell import CellPhysics

__all__ = [
    "EgmControllerConfig",
    "EgmControllerEmulator",
    "EgmControllerModel",
    "EgmFaultConfig",
    "Fault",
    "LagServo",
    "ServoParams",
    "start_emulated_egm",
]


def start_emulated_egm(
    physics: CellPhysics,
    clock: SimClock,
    remote_port: int,
    config: EgmControllerConfig | None = None,
    faults: EgmFaultConfig | None = None,
) -> EgmControllerEmulator:
    """Start an emulated EGM controller for an emulated cell (lockstep) and return it.

    ``remote_port`` is the driver's bound port (``EgmRobotDriver.port``); the
    driver must be configured with ``lockstep = True``. Stop it with ``stop()``.
    """
    emulator = EgmControllerEmulator(
        remote_port, physics=physics, clock=clock, config=config, faults=faults, lockstep=True
    )
    emulator.start()
    return emulator
