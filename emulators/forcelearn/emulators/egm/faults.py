"""Fault injection for the EGM controller emulator: a hook, not a fork of the code.

Each :class:`Fault` fires with a probability, at most ``limit`` times
(``Fault(1.0, limit=1)`` is "exactly the next one"); randomness comes from a
seeded ``numpy.random.Generator``, so a failing run can be replayed.

===============  ===============================================================
fault            effect (per controller cycle)
===============  ===============================================================
lose             the cycle's EgmRobot is never sent (the PC sees a seqno gap)
duplicate        the cycle's EgmRobot is sent twice
reorder          the cycle's EgmRobot is held back and sent after the next one
lose_reply       the PC's EgmSensor is lost: the controller keeps the last one
late_reply       the PC's EgmSensor arrives after the next cycle has started: the
                 controller uses it one cycle late (the last one meanwhile)
restart          the controller restarts guidance: a new session, seqno 0
===============  ===============================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field

from forcelearn.emulators.faults import Fault, FaultInjectorBase

FAULT_NAMES = ("lose", "duplicate", "reorder", "lose_reply", "late_reply", "restart")


@dataclass(frozen=True)
class EgmFaultConfig:
    """Which faults the emulator injects; the default injects none.

    ``after_cycles``: no fault fires during the first cycles of the emulator
    (so a driver can open cleanly before the faults begin).
    """

    lose: Fault = field(default_factory=Fault)
    duplicate: Fault = field(default_factory=Fault)
    reorder: Fault = field(default_factory=Fault)
    lose_reply: Fault = field(default_factory=Fault)
    late_reply: Fault = field(default_factory=Fault)
    restart: Fault = field(default_factory=Fault)
    after_cycles: int = 0
    seed: int = 0


class EgmFaultInjector(FaultInjectorBase[EgmFaultConfig]):
    """Decides, cycle by cycle, whether a fault of :data:`FAULT_NAMES` fires. Thread-safe."""

    def __init__(self, config: EgmFaultConfig | None = None) -> None:
        super().__init__(config or EgmFaultConfig())
        self.cycle = 0
        """The emulator's cycle count, set by the emulator before it asks."""
        self.none_armed = all(getattr(self.config, name).probability == 0.0
                              for name in FAULT_NAMES)
        """No fault can ever fire (every probability is 0): every datagram goes as built."""

    def _armed(self) -> bool:
        """No fault fires during the first ``after_cycles`` cycles."""
        return self.cycle >= self.config.after_cycles
