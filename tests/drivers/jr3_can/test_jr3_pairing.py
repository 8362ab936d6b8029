"""Pairing by counter, unpaired frames and gap counting across the 16-bit wrap."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.drivers.jr3_can.pairing import Pairer, counter_gap
from forcelearn.protocols.jr3_can.codec import Forces, Moments
from forcelearn.protocols.jr3_can.opcodes import CounterMeaning


def _f(counter: int) -> Forces:
    return Forces((counter % 100, 2, 3), counter)


def _m(counter: int) -> Moments:
    return Moments((4, 5, 6), counter)


def test_counter_gap_handles_the_wrap() -> None:
    """65534 -> 1 skips 65535 and 0; consecutive counters skip nothing; a repeat is -1."""
    assert counter_gap(65534, 1) == 2
    assert counter_gap(65535, 0) == 0
    assert counter_gap(10, 11) == 0
    assert counter_gap(7, 7) == -1


def test_pairs_only_matching_counters_in_either_order() -> None:
    """A pair forms from equal counters whichever frame comes first."""
    pairer = Pairer()
    assert pairer.push(_f(1)) is None
    pair = pairer.push(_m(1))
    assert pair is not None and pair.raw == (1, 2, 3, 4, 5, 6) and pair.counter == 1
    assert pairer.push(_m(2)) is None
    pair = pairer.push(_f(2))
    assert pair is not None and pair.counter == 2 and pair.dropped == 0


def test_mismatched_counters_do_not_pair_and_are_counted() -> None:
    """A force frame whose moment frame was lost is discarded when the next counter comes."""
    pairer = Pairer()
    pairer.push(_f(1))
    assert pairer.push(_m(2)) is None
    assert pairer.unpaired == 1
    pair = pairer.push(_f(2))
    assert pair is not None and pair.counter == 2


def test_sensor_frame_counter_steps_are_elapsed_time_not_losses() -> None:
    """Sensor frame counter steps are elapsed time not losses.

    The current firmware's counter counts sensor frames: pairs 65530, 65537 -> 1, 9 step by 7, 8
    frames across the wrap; nothing is called dropped. (This test used to count such steps as
    dropped samples: the meaning of the firmware before 2023-12-27, kept below.)
    """
    pairer = Pairer()
    counters = [65530, 1, 9]
    pairs = [pairer.push(_f(c)) or pairer.push(_m(c)) for c in counters]
    assert [p.elapsed for p in pairs if p] == [None, 7, 8]
    assert [p.dropped for p in pairs if p] == [0, 0, 0] and pairer.dropped == 0


def test_dropped_samples_counted_across_the_wrap_with_a_message_counter() -> None:
    """Dropped samples counted across the wrap with a message counter.

    Firmware 2023-09-25..2023-12-26 counted pairs sent: 65533, 65534, then 1, 2 lost two samples
    (65535, 0).
    """
    pairer = Pairer(CounterMeaning.TRANSMITTED_SAMPLES)
    counters = [65533, 65534, 1, 2]
    pairs = [pairer.push(_f(c)) or pairer.push(_m(c)) for c in counters]
    assert [p.counter for p in pairs if p] == counters
    assert [p.dropped for p in pairs if p] == [0, 0, 2, 0]
    assert pairer.dropped == 2


def test_duplicate_counter_is_discarded() -> None:
    """A repeated pair is counted as duplicate and not returned."""
    pairer = Pairer()
    pairer.push(_f(5))
    pairer.push(_m(5))
    pairer.push(_f(5))
    assert pairer.push(_m(5)) is None
    assert pairer.duplicates == 1


def test_restart_forgets_the_counter() -> None:
    """After a bootup the counter restarts at 0 without being called a gap."""
    pairer = Pairer()
    pairer.push(_f(900))
    pairer.push(_m(900))
    pairer.restart()
    pairer.push(_f(0))
    pair = pairer.push(_m(0))
    assert pair is not None and pair.dropped == 0 and pairer.dropped == 0


def test_pending_newer_frame_is_kept_or_counted_when_a_pair_completes() -> None:
    """Out of order, M(11) waits while F(10), M(10) pair; it is not lost silently."""
    pairer = Pairer()
    pairer.push(_m(11))
    pairer.push(_f(10))
    pair = pairer.push(_m(10))
    assert pair is not None and pair.counter == 10
    assert pairer.pending == 1  # M(11) still waits for F(11)
    pair = pairer.push(_f(11))
    assert pair is not None and pair.counter == 11
    assert pairer.unpaired == 0 and pairer.pending == 0


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.integers(0, 6)), max_size=60))
def test_every_pushed_frame_is_accounted_for(frames: list[tuple[bool, int]]) -> None:
    """Any order of frames: pushed = 2 x (pairs + duplicates) + unpaired + pending."""
    pairer = Pairer()
    pairs = 0
    for is_force, counter in frames:
        pairs += pairer.push(_f(counter) if is_force else _m(counter)) is not None
    accounted = 2 * (pairs + pairer.duplicates) + pairer.unpaired + pairer.pending
    assert accounted == len(frames)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 0xFFFF), max_size=40), st.booleans())
def test_push_both_is_a_forces_then_a_moments_push(counters: list[int], by_message: bool) -> None:
    """The in-process route's pair (six counts, one counter) as the two pushes give it."""
    meaning = CounterMeaning.TRANSMITTED_SAMPLES if by_message else CounterMeaning.SENSOR_FRAMES
    two, both = Pairer(meaning), Pairer(meaning)
    for n, counter in enumerate(counters):
        raw = (n, -n, 2 * n, 3, -4, n % 7)
        assert two.push(Forces(raw[:3], counter)) is None
        expected = two.push(Moments(raw[3:], counter))
        assert both.push_both(raw, counter) == expected
        assert (both.dropped, both.duplicates, both.unpaired, both.pending) == (
            two.dropped, two.duplicates, two.unpaired, two.pending)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 0xFFFF), max_size=40), st.booleans())
def test_step_to_is_push_both_without_the_pair(counters: list[int], by_message: bool) -> None:
    """``step_to`` (the listener's carried sample) counts as ``push_both``; its elapsed."""
    meaning = CounterMeaning.TRANSMITTED_SAMPLES if by_message else CounterMeaning.SENSOR_FRAMES
    both, stepped = Pairer(meaning), Pairer(meaning)
    for n, counter in enumerate(counters):
        pair = both.push_both((n, 0, 0, 0, 0, 0), counter)
        elapsed = stepped.step_to(counter)
        assert elapsed == (-1 if pair is None else pair.elapsed or 0)
        assert (stepped.dropped, stepped.duplicates) == (both.dropped, both.duplicates)
        if n == 20:
            both.restart()
            stepped.restart()


def test_push_both_refuses_a_pending_frame() -> None:
    """With a frame waiting for its partner the two pushes must be made one by one."""
    pairer = Pairer()
    pairer.push(_f(3))
    with pytest.raises(ValueError, match="pending"):
        pairer.push_both((1, 2, 3, 4, 5, 6), 4)
