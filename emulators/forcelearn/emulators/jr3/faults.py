"""Fault injection for the JR3 emulator: what goes wrong on the wire, as data.

Faults act on outgoing frames after the device model, so the model and the
protocol code stay the same whether faults are on or off. A test may also pass
a ``frame_hook`` to the node to drop or alter chosen frames deterministically.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from forcelearn.deprecation import renamed
from forcelearn.protocols.jr3_can.codec import Frame

FrameHook = Callable[[Frame], Frame | None]
"""Gets each outgoing frame; returns it (maybe changed) or None to drop it."""


@dataclass(frozen=True)
class Jr3FaultConfig:
    """Wire faults of the emulated adapter.

    Attributes:
        drop_probability: chance that any outgoing frame is lost.
        corrupt_length_probability: chance that a frame's payload is cut or padded.
        silent: send nothing at all (no ACKs, no samples), as a dead adapter.
        bootup_after_samples: send a bootup frame (and reboot) after this many samples.
    """

    drop_probability: float = 0.0
    corrupt_length_probability: float = 0.0
    silent: bool = False
    bootup_after_samples: int | None = None

    def __post_init__(self) -> None:
        for name in ("drop_probability", "corrupt_length_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"faults {name} must be in [0, 1]")
        if self.bootup_after_samples is not None and self.bootup_after_samples < 1:
            raise ValueError("faults bootup_after_samples must be >= 1 or None")


def apply_faults(frame: Frame, faults: Jr3FaultConfig, rng: np.random.Generator) -> Frame | None:
    """Return the frame as the faults let it out: unchanged, corrupted, or None (lost)."""
    if faults.silent:
        return None
    if faults.drop_probability and rng.random() < faults.drop_probability:
        return None
    if faults.corrupt_length_probability and rng.random() < faults.corrupt_length_probability:
        lengths = [n for n in range(9) if n != len(frame.data)]
        size = int(rng.choice(lengths))
        data = (frame.data + bytes(8))[:size]
        return Frame(frame.arbitration_id, data)
    return frame


__getattr__ = renamed(__name__, {"FaultConfig": Jr3FaultConfig})
