"""The ``link`` fuzz target: mutated streams of computer-link reply frames.

The wire bytes of one to three replies, mutated, are fed in chunks to the
FrameReader; every accepted payload must be one sent, and ``decode_reply``
raises only ProtocolError.
"""

from __future__ import annotations

import random
from collections import Counter
from collections.abc import Sequence

from forcelearn.errors import ForcelearnError
from forcelearn.tools.fuzz.harness import FuzzFailure, foreign


def link_stream(payloads: Sequence[bytes]) -> bytes:
    """The wire bytes of ``payloads`` sent one after another."""
    from forcelearn.protocols.computer_link import framing

    return b"".join(framing.encode(p) for p in payloads)


def check_link(sent: Sequence[bytes], received: bytes, chunk: int = 7) -> str:
    """Feed ``received`` to a FrameReader; "accepted" if every sent frame came through."""
    from forcelearn.protocols.computer_link import framing
    from forcelearn.protocols.computer_link import messages as m

    reader = framing.FrameReader()
    accepted: list[bytes] = []
    try:
        for i in range(0, len(received), chunk):
            for frame in reader.feed(received[i : i + chunk]):
                if isinstance(frame, framing.DataFrame):
                    accepted.append(frame.payload)
    except Exception as exc:
        raise foreign(exc, "FrameReader.feed") from exc
    extra = Counter(accepted) - Counter(sent)
    if extra:
        raise FuzzFailure(f"accepted payload(s) never sent: {list(extra)!r}")
    for payload in accepted:
        try:
            m.decode_reply(payload)
        except ForcelearnError:
            pass
        except Exception as exc:
            raise foreign(exc, "decode_reply") from exc
    return "accepted" if Counter(accepted) == Counter(sent) else "rejected"


def random_replies(rng: random.Random) -> list[bytes]:
    """One to three reply payloads of the kinds the controller sends."""
    from forcelearn.protocols.computer_link import messages as m

    payloads = []
    for _ in range(rng.randint(1, 3)):
        command = rng.choice(list(m.Command))
        tns = rng.randrange(0x10000)
        if rng.random() < 0.2:
            reply = m.Reply(command, tns, int(m.ErrorCode.OUT_OF_WORKSPACE), reason="refused")
        elif command is m.Command.READ_POSITION:
            values = [rng.uniform(-2000, 2000) for _ in range(13)]
            body = m.position_body(m.Position(values[:3], values[3:7], values[7:]))  # type: ignore[arg-type]
            reply = m.Reply(command, tns, m.ErrorCode.OK, body=body)
        else:
            reply = m.Reply(command, tns, m.ErrorCode.OK)
        payloads.append(m.encode_reply(reply))
    return payloads
