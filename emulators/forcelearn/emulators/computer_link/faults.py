"""Fault injection for the robot-controller emulator: a hook, not a fork of the code.

Each :class:`Fault` fires with a probability, at most ``limit`` times
(``Fault(1.0, limit=1)`` is "exactly the next one"). Randomness comes from a
seeded ``numpy.random.Generator`` so a failing run can be replayed.

=================  ===========================================================
fault              effect
=================  ===========================================================
corrupt_byte       each byte received or sent has one random bit pattern XORed
drop_request       a received request frame is ignored, as if lost on the wire
drop_reply         a reply frame is not sent (the request *was* executed)
delay_ack          the controller sleeps ``ack_delay_s`` before its DLE ACK
drop_connection    after executing a request, hang up instead of answering
stall_fraction     every move stops at this fraction of its way (never in position)
never_in_position  READ_STATUS never reports in position
=================  ===========================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field

from forcelearn.deprecation import renamed
from forcelearn.emulators.faults import Fault as Fault  # re-exported: its old home
from forcelearn.emulators.faults import FaultInjectorBase


@dataclass(frozen=True)
class ComputerLinkFaultConfig:
    """Which faults the emulator injects; the default injects none."""

    corrupt_byte: Fault = field(default_factory=Fault)
    drop_request: Fault = field(default_factory=Fault)
    drop_reply: Fault = field(default_factory=Fault)
    delay_ack: Fault = field(default_factory=Fault)
    drop_connection: Fault = field(default_factory=Fault)
    ack_delay_s: float = 0.5
    stall_fraction: float | None = None
    never_in_position: bool = False
    seed: int = 0


class FaultInjector(FaultInjectorBase[ComputerLinkFaultConfig]):
    """Decides, call by call, whether a fault fires; counts what fired. Thread-safe."""

    def __init__(self, config: ComputerLinkFaultConfig | None = None) -> None:
        super().__init__(config or ComputerLinkFaultConfig())

    def corrupt(self, data: bytes) -> bytes:
        """Return ``data`` with each byte damaged with the corrupt_byte probability."""
        if self.config.corrupt_byte.probability == 0.0:
            return data
        out = bytearray(data)
        for i in range(len(out)):
            if self.fires("corrupt_byte"):
                with self._lock:
                    out[i] ^= int(self._rng.integers(1, 256))
        return bytes(out)

    def drop_request(self) -> bool:
        """True if the request just received is to be lost."""
        return self.fires("drop_request")

    def drop_reply(self) -> bool:
        """True if the reply about to be sent is to be lost."""
        return self.fires("drop_reply")

    def ack_delay_s(self) -> float:
        """Seconds to wait before the next DLE ACK (0 when the fault does not fire)."""
        return self.config.ack_delay_s if self.fires("delay_ack") else 0.0

    def drop_connection(self) -> bool:
        """True if the controller should hang up now."""
        return self.fires("drop_connection")


__getattr__ = renamed(__name__, {"FaultConfig": ComputerLinkFaultConfig})
