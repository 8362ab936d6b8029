"""The fuzz harness's primitives: byte mutations, the failure every check raises, the tally.

Every target (:mod:`forcelearn.tools.fuzz.targets` and its sibling modules)
mutates good bytes with :func:`apply_mutations` of :func:`random_mutations`,
checks the two properties (no foreign exception, no accepted corruption) and
raises :class:`FuzzFailure` when one fails; :class:`Tally` counts the outcomes.
"""

from __future__ import annotations

import random
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

Mutation = tuple[int, int, int]
"""(kind, position, value): kind 0 flip a bit, 1 set a byte, 2 insert, 3 delete, 4 truncate."""
MUTATION_KINDS = 5
INTERESTING_BYTES = (0x00, 0x10, 0x02, 0x03, 0xFF, 0x0A, 0x22, 0x5B, 0x30, 0x39)


class FuzzFailure(AssertionError):
    """A property failed: a foreign exception escaped, or a corruption was accepted."""


def apply_mutations(data: bytes, mutations: Iterable[Mutation]) -> bytes:
    """Return ``data`` with each mutation applied in turn (positions taken modulo the size)."""
    out = bytearray(data)
    for operation, position, value in mutations:
        size = len(out)
        at = position % (size + 1)
        if operation == 0 and size:
            out[at % size] ^= 1 << (value % 8)
        elif operation == 1 and size:
            out[at % size] = value & 0xFF
        elif operation == 2:
            out[at:at] = bytes((value & 0xFF,)) * (1 + (value >> 8) % 3)
        elif operation == 3 and size:
            del out[at : at + 1 + (value >> 8) % 3]
        elif operation == 4:
            del out[at:]
    return bytes(out)


def random_mutations(rng: random.Random, max_count: int = 4) -> list[Mutation]:
    """Draw 1..max_count mutations, biased towards the protocol's special bytes."""
    mutations = []
    for _ in range(rng.randint(1, max_count)):
        operation = rng.choices(range(MUTATION_KINDS), weights=(4, 3, 3, 2, 1))[0]
        byte = rng.choice(INTERESTING_BYTES) if rng.random() < 0.5 else rng.randrange(256)
        mutations.append((operation, rng.randrange(1 << 20), byte | rng.randrange(4) << 8))
    return mutations


def foreign(exc: BaseException, what: str) -> FuzzFailure:
    """The failure of a foreign exception ``exc`` escaping ``what``."""
    return FuzzFailure(f"{what} raised {type(exc).__name__}: {exc}")


@dataclass
class Tally:
    """Outcome of one target's run."""

    inputs: int = 0
    outcomes: Counter[str] = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)

    def add(self, run: Callable[[], str]) -> None:
        """Run one input and count its outcome (a FuzzFailure is recorded, not raised)."""
        self.inputs += 1
        try:
            self.outcomes[run()] += 1
        except FuzzFailure as exc:
            kind = "accepted corruption" if "raised" not in str(exc) else "foreign exception"
            self.outcomes[kind] += 1
            if len(self.failures) < 10:
                self.failures.append(str(exc))
