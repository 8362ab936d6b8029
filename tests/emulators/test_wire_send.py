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


def test_a_transmit_wrapped_on_the_wire_sees_every_send() -> None:
    """``step_timeline`` logs a wire by wrapping ``transmit`` on it: a send goes through it."""
    clock = SimClock()
    wire = Wire(clock)
    log: list[tuple[float, float]] = []
    transmit = wire.transmit

    def logged(duration_s: float, ready_s: float | None = None) -> tuple[float, float]:
        start, end = transmit(duration_s, ready_s)
        log.append((start, end))
        return start, end

    wire.transmit = logged  # type: ignore[method-assign]
    assert wire.send(0.002) == 0.002 and wire.send(0.001, 0.0005) == 0.003
    assert log == [(0.0, 0.002), (0.002, 0.003)] and clock.now_s == 0.003
