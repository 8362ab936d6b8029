"""The ``can`` fuzz target: JR3 CAN frames through the codec and the driver's listener.

Valid frames of the node (some mutated) and random frames: a decoded frame
must encode back to the same bytes, every sample must equal a received
force/moment pair scaled, and every frame is accounted for.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import can
import numpy as np

from forcelearn.tools.fuzz.harness import FuzzFailure, apply_mutations, foreign, random_mutations

if TYPE_CHECKING:
    from forcelearn.devices import WrenchSample

FUZZ_NODE = 1
FUZZ_FULL_SCALES = np.array([200.0, 200.0, 400.0, 20.0, 20.0, 20.0])


@dataclass
class CanFrame:
    """One frame as python-can would deliver it."""

    arbitration_id: int
    data: bytes
    is_extended_id: bool = False
    is_remote_frame: bool = False
    is_error_frame: bool = False

    def message(self) -> can.Message:
        """The python-can message (data cut to the 8 bytes CAN carries)."""
        return can.Message(arbitration_id=self.arbitration_id, data=self.data[:8],
                           is_extended_id=self.is_extended_id,
                           is_remote_frame=self.is_remote_frame,
                           is_error_frame=self.is_error_frame, check=False)


def check_can(frames: Sequence[CanFrame]) -> str:
    """Codec round trip, listener never raising, samples equal to received pairs."""
    from forcelearn.drivers.jr3_can.listener import Jr3Listener
    from forcelearn.protocols.jr3_can import codec
    from forcelearn.protocols.jr3_can.opcodes import JR3_MBED_2023_12

    listener = Jr3Listener(FUZZ_NODE, JR3_MBED_2023_12, 26214)
    listener.set_full_scales(FUZZ_FULL_SCALES)
    samples: list[WrenchSample] = []
    listener.callbacks.append(samples.append)
    forces: dict[int, list[tuple[int, ...]]] = {}
    moments: dict[int, list[tuple[int, ...]]] = {}
    decoded_any = False
    for frame in frames:
        msg = frame.message()
        try:
            result = codec.decode(msg.arbitration_id, msg.data, is_extended_id=msg.is_extended_id,
                                  opcodes=JR3_MBED_2023_12)
        except Exception as exc:
            raise foreign(exc, "codec.decode") from exc
        if isinstance(result, codec.Decoded):
            decoded_any = True
            again = codec.encode(result.message, result.node_id or 1, JR3_MBED_2023_12)
            if (again.arbitration_id, again.data) != (msg.arbitration_id, bytes(msg.data)):
                raise FuzzFailure(f"{msg} decoded to {result}, which encodes to {again}")
            accepted = not (msg.is_remote_frame or msg.is_error_frame)
            if accepted and result.node_id == FUZZ_NODE:
                if isinstance(result.message, codec.Forces):
                    forces.setdefault(result.message.counter, []).append(result.message.raw)
                elif isinstance(result.message, codec.Moments):
                    moments.setdefault(result.message.counter, []).append(result.message.raw)
        try:
            listener.on_message_received(msg)
        except Exception as exc:
            raise foreign(exc, "Jr3Listener.on_message_received") from exc
    scale = FUZZ_FULL_SCALES / 16384
    for sample in samples:
        raw = np.rint(sample.wrench / scale).astype(int)
        f, mo = tuple(raw[:3].tolist()), tuple(raw[3:].tolist())
        if f not in forces.get(sample.counter, ()) or mo not in moments.get(sample.counter, ()):
            raise FuzzFailure(f"sample {sample} matches no received pair")
    stats = listener.stats()
    axes_frames = sum(len(v) for v in forces.values()) + sum(len(v) for v in moments.values())
    paired = stats.samples + stats.samples_before_full_scales + stats.duplicate_samples
    if stats.frames != len(frames):
        raise FuzzFailure(f"listener counted {stats.frames} frames of {len(frames)}")
    if axes_frames != 2 * paired + stats.unpaired_frames + stats.pending_frames:
        raise FuzzFailure(f"{axes_frames} force/moment frames but {stats} account for others")
    return "accepted" if decoded_any else "rejected"


def random_can_frames(rng: random.Random) -> list[CanFrame]:
    """A short burst: valid frames of the node (some mutated) and random frames."""
    from forcelearn.protocols.jr3_can import codec
    from forcelearn.protocols.jr3_can.opcodes import JR3_MBED_2023_12

    frames = []
    counter = rng.randrange(0x10000)
    for _ in range(rng.randint(1, 12)):
        roll = rng.random()
        if roll < 0.6:
            raw = tuple(rng.randint(-32768, 32767) for _ in range(3))
            kind = codec.Forces if rng.random() < 0.5 else codec.Moments
            counter = (counter + rng.choice((0, 0, 1, 2))) % 0x10000
            message: codec.Message = kind(raw, counter)  # type: ignore[arg-type]
            if rng.random() < 0.1:
                message = codec.Ack(rng.randrange(2), (rng.randrange(0x10000),) * 3)
            wire = codec.encode(message, FUZZ_NODE, JR3_MBED_2023_12)
            data = wire.data
            if rng.random() < 0.3:
                data = apply_mutations(data, random_mutations(rng, 2))
            frames.append(CanFrame(wire.arbitration_id, data))
        else:
            frames.append(CanFrame(
                rng.randrange(1 << (29 if roll > 0.95 else 11)),
                rng.randbytes(rng.randint(0, 8)),
                is_extended_id=roll > 0.95,
                is_remote_frame=rng.random() < 0.05,
                is_error_frame=rng.random() < 0.05,
            ))
    return frames
