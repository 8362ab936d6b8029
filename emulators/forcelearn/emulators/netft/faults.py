"""Fault injection for the Net F/T emulator: what goes wrong on the wire, as data.

Faults act on the records of one request after the sensor model, so the
model and the protocol code are the same with faults on or off. A test may
pass a ``records_hook`` to drop, repeat or reorder chosen records
deterministically.

=========================  =====================================================
fault                      effect
=========================  =====================================================
``drop_probability``       a record is lost (UDP has no retransmission)
``duplicate_probability``  a record is sent twice in a row
``reorder_probability``    a record swaps places with the next one
``silent``                 no RDT record at all (a dead box or a pulled cable)
``status``                 every record carries this status word (0 = healthy)
``reboot_after_records``   after this many records the box reboots: the stream
                           stops, ``ft_sequence`` restarts, the software bias
                           is forgotten
=========================  =====================================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from forcelearn.protocols.netft import Record

RecordsHook = Callable[[list[Record]], list[Record]]
"""Gets the records of one request (after the faults); returns what is sent, in order."""


@dataclass(frozen=True)
class NetFtFaults:
    """Wire faults of the emulated box (see the module table)."""

    drop_probability: float = 0.0
    duplicate_probability: float = 0.0
    reorder_probability: float = 0.0
    silent: bool = False
    status: int = 0
    reboot_after_records: int | None = None

    def __post_init__(self) -> None:
        for name in ("drop_probability", "duplicate_probability", "reorder_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"netft faults {name} must be in [0, 1]")
        if not 0 <= self.status <= 0xFFFFFFFF:
            raise ValueError("netft faults status must be a u32")
        if self.reboot_after_records is not None and self.reboot_after_records < 1:
            raise ValueError("netft faults reboot_after_records must be >= 1 or None")


@dataclass
class FaultCounts:
    """What the faults did (the emulator's side of the accounting)."""

    dropped: int = 0
    duplicated: int = 0
    reordered: int = 0


def apply_faults(records: list[Record], faults: NetFtFaults, rng: np.random.Generator,
                 counts: FaultCounts) -> list[Record]:
    """Return the records as the faults let them out (dropped, duplicated, swapped)."""
    if faults.silent:
        counts.dropped += len(records)
        return []
    out: list[Record] = []
    for record in records:
        if faults.drop_probability and rng.random() < faults.drop_probability:
            counts.dropped += 1
            continue
        out.append(record)
        if faults.duplicate_probability and rng.random() < faults.duplicate_probability:
            counts.duplicated += 1
            out.append(record)
    if faults.reorder_probability:
        i = 0
        while i < len(out) - 1:
            if _swappable(out, i) and rng.random() < faults.reorder_probability:
                out[i], out[i + 1] = out[i + 1], out[i]
                counts.reordered += 1
                i += 2
            else:
                i += 1
    return out


def _swappable(out: list[Record], i: int) -> bool:
    """Swap only two different records with no copy beside them, so each swap is one late one."""
    return (out[i] != out[i + 1] and (i == 0 or out[i - 1] != out[i])
            and (i + 2 >= len(out) or out[i + 2] != out[i + 1]))
