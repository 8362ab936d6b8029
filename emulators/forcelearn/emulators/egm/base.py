"""What both routes of the emulated EGM controller share: model, faults, cycle grid, checkpoint."""

from __future__ import annotations

import threading
from typing import Any

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.controller import HOME, EgmControllerConfig, EgmControllerModel
from forcelearn.emulators.egm.cycles import CycleLoop
from forcelearn.emulators.egm.faults import EgmFaultConfig, EgmFaultInjector
from forcelearn.emulators.egm.servo import MotionModel
from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.physics.cell import CellPhysics


class EgmEmulatorBase(Emulator):
    """An emulated ABB controller running EGM pose guidance (the route is the subclass').

    Args:
        physics: shared cell physics (default: a fresh one at ``controller.HOME``).
        clock: the cell's simulated clock (default: a new one, as fast as possible).
        config: controller settings (version, sample rate, CommTimeout, servo).
        faults: fault injection (default: none).
        motion: the arm's motion model (default: the config's dead time + lag servo).
    """

    def __init__(
        self,
        *,
        physics: CellPhysics | None = None,
        clock: SimClock | None = None,
        config: EgmControllerConfig | None = None,
        faults: EgmFaultConfig | None = None,
        motion: MotionModel | None = None,
    ) -> None:
        self.clock = clock or SimClock()
        self.config = config or EgmControllerConfig()
        self.physics = physics or CellPhysics(pose=HOME)
        self.model = EgmControllerModel(self.config, self.physics, self.clock.now_s, motion)
        self.faults = EgmFaultInjector(faults)
        self.loop = CycleLoop(self.model, self.faults, self.clock, self.config.sample_period_s)
        self.replies = 0
        """EgmSensor datagrams received."""

    @property
    def cycles(self) -> int:
        """Cycles run (EgmRobot datagrams built, sent or not)."""
        return self.loop.cycles

    @property
    def guidance_stopped(self) -> threading.Event:
        """Set when guidance ends (CommTimeout or motion error); cleared by a restart."""
        return self.loop.guidance_stopped

    def restart_guidance(self) -> None:
        """Restart the RAPID program (operator action): a new session from the next cycle."""
        self.loop.restart_requested.set()

    def state_dict(self) -> dict[str, Any]:
        """The controller's state and its cycle time (JSON-able; the arm is the physics')."""
        return self.loop.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` while the controller waits for the PC's answer.

        The next cycle then follows the restored one, as if the run had never
        stopped. Fault injection is not restored (the emulated cell runs none).
        """
        self.loop.load_state_dict(state)
