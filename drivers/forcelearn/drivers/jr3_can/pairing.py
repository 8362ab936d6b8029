"""Pure pairing of force and moment frames, and the counter's steps across the 16-bit wrap.

A force frame and a moment frame form one sample only when their frame
counters match. Frames whose partner never comes are counted as unpaired.
What a step of the counter between two pairs means depends on the firmware
(:class:`~forcelearn.protocols.jr3_can.opcodes.CounterMeaning`): since
2023-12-27 it counts sensor frames, so the step is sensor time (``elapsed``)
and says nothing of losses; before, it counted pairs sent, so a gap is that
many dropped samples. No clock, no bus: the listener feeds frames in arrival order.
"""

from __future__ import annotations

from dataclasses import dataclass

from forcelearn.protocols.jr3_can.codec import COUNTER_MODULUS, Forces, Moments
from forcelearn.protocols.jr3_can.opcodes import CounterMeaning


def counter_gap(previous: int, current: int) -> int:
    """Return how many counters lie strictly between two paired counters (wrap-aware).

    ``counter_gap(65534, 1) == 2`` (65535 and 0 are missing); a repeated counter
    gives -1 (a duplicate, not a gap).
    """
    return (current - previous) % COUNTER_MODULUS - 1


@dataclass(frozen=True, slots=True)
class Pair:
    """A matched force/moment pair: six raw counts and their counter.

    ``elapsed``: counter steps since the previous pair (wrap-aware; None for the
    first pair after a start); ``dropped``: samples known lost before it (only
    when the counter counts pairs sent).
    """

    raw: tuple[int, int, int, int, int, int]
    counter: int
    dropped: int
    elapsed: int | None = None


def _forces_first(a: Forces | Moments, b: Forces | Moments) -> tuple[Forces, Moments]:
    """Return a force and a moment frame, forces first, whichever order they come in."""
    if isinstance(a, Forces) and isinstance(b, Moments):
        return a, b
    if isinstance(a, Moments) and isinstance(b, Forces):
        return b, a
    raise TypeError(f"expected a force and a moment frame, got {a!r} and {b!r}")


class Pairer:
    """Match frames by counter and count what is lost; one instance per stream.

    Args:
        counter: what the counter counts (the firmware's meaning).

    Attributes:
        unpaired: frames discarded because no partner with the same counter came.
        dropped: samples skipped between consecutive pairs (wrap-aware), counted
            only when the counter counts pairs sent (older firmware).
        duplicates: pairs whose counter repeated the previous one (discarded).
    """

    def __init__(self, counter: CounterMeaning = CounterMeaning.SENSOR_FRAMES) -> None:
        self.gaps_are_losses = counter is CounterMeaning.TRANSMITTED_SAMPLES
        self.unpaired = 0
        self.dropped = 0
        self.duplicates = 0
        self._forces: Forces | None = None
        self._moments: Moments | None = None
        self._last_counter: int | None = None

    @property
    def pending(self) -> int:
        """Frames held waiting for their partner (0, 1 or 2).

        Every pushed frame is accounted for: ``pushed == 2 * (pairs returned +
        duplicates) + unpaired + pending``.
        """
        return (self._forces is not None) + (self._moments is not None)

    def restart(self) -> None:
        """Forget pending frames and the last counter.

        After a start, reset or bootup the adapter's counter starts again from 0.
        """
        self.unpaired += (self._forces is not None) + (self._moments is not None)
        self._forces = self._moments = None
        self._last_counter = None

    def push(self, frame: Forces | Moments) -> Pair | None:
        """Add one frame; return the pair it completes, or None."""
        other: Forces | Moments | None
        if isinstance(frame, Forces):
            mine, other = "_forces", self._moments
        else:
            mine, other = "_moments", self._forces
        if other is not None and other.counter == frame.counter:
            forces, moments = _forces_first(frame, other)
            waiting = getattr(self, mine)  # a frame of this kind that arrived out of order
            if waiting is not None and not self._is_older(frame.counter, waiting.counter):
                self.unpaired += 1  # older than this pair: its partner is gone
                waiting = None
            self._forces = self._moments = None
            setattr(self, mine, waiting)  # a newer one keeps waiting for its partner
            return self._complete(forces, moments)
        if getattr(self, mine) is not None:
            self.unpaired += 1
        if other is not None and self._is_older(other.counter, frame.counter):
            # the partner of the older frame can no longer come before this one
            self.unpaired += 1
            if isinstance(frame, Forces):
                self._moments = None
            else:
                self._forces = None
        setattr(self, mine, frame)
        return None

    @staticmethod
    def _is_older(counter: int, than: int) -> bool:
        return 0 < (than - counter) % COUNTER_MODULUS < COUNTER_MODULUS // 2

    def push_both(self, raw: tuple[int, int, int, int, int, int], counter: int) -> Pair | None:
        """:meth:`push` of a Forces then a Moments frame of ``counter``; needs nothing pending.

        What the two pushes give when no frame waits (the in-process route's sample,
        handed over as its six counts): the pair they complete, or None.
        """
        if self._forces is not None or self._moments is not None:
            raise ValueError("push_both needs no frame pending: push each frame instead")
        return self._complete_counts(raw, counter)

    def _complete(self, forces: Forces, moments: Moments) -> Pair | None:
        return self._complete_counts((*forces.raw, *moments.raw), forces.counter)

    def _complete_counts(self, raw: tuple[int, int, int, int, int, int], counter: int
                         ) -> Pair | None:
        elapsed = self.step_to(counter)
        if elapsed < 0:
            return None
        if elapsed == 0:
            return Pair(raw, counter, 0, None)
        return Pair(raw, counter, elapsed - 1 if self.gaps_are_losses else 0, elapsed)

    def step_to(self, counter: int) -> int:
        """The counter of a completed pair: counted as :meth:`push` counts it; its elapsed steps.

        Returns ``Pair.elapsed`` (0 for the first pair after a start, whose ``elapsed`` is
        None), or -1 for a duplicate (no pair). What :meth:`push_both` does without the
        Pair built (the in-process route's sample, nothing pending).
        """
        last = self._last_counter
        if last is None:
            self._last_counter = counter
            return 0
        gap = counter_gap(last, counter)
        if gap < 0:
            self.duplicates += 1
            return -1
        self._last_counter = counter
        if self.gaps_are_losses:
            self.dropped += gap
        return gap + 1
