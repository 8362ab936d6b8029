"""``Wire.send`` (the in-process routes' frame) is ``transmit`` then the clock moved to its end."""

from __future__ import annotations

import random

from forcelearn.emulators.clock import SimClock, Wire


def test_send_is_transmit_then_advance_to_its_end() -> None:
    """Frames now and from a ready time before or after now, the wire busy or free."""
    rng = random.Random(9)
    one, two = SimClock(), SimClock()
    by_send, by_transmit = Wire(one), Wire(two)
    for _ in range(2000):
        duration = rng.choice((0.0, 1e-4, rng.uniform(0.0, 0.01)))
        ready = rng.choice((None, one.now_s - 0.003, one.now_s + rng.uniform(0.0, 0.01)))
        if rng.random() < 0.2:  # the clock moved by someone else between frames
            step = rng.uniform(0.0, 0.02)
            one.advance(step)
            two.advance(step)
        end = by_send.send(duration, ready)
        _, expected = by_transmit.transmit(duration, ready)
        two.advance_to(expected)
        assert (end, one.now_s, by_send.free_at_s) == (expected, two.now_s, by_transmit.free_at_s)
