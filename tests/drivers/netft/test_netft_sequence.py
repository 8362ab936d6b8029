"""RDT sequence accounting: lost, duplicated, out-of-order, wrap, lost tail, reboot."""

from __future__ import annotations

from forcelearn.drivers.netft.sequence import SequenceTracker, Verdict, ahead


def feed(tracker: SequenceTracker, sequences: list[int], ft0: int = 100) -> list[Verdict]:
    """Push rdt sequences with ft_sequence = ft0 + rdt; return the verdicts."""
    return [tracker.push(s, ft0 + s).verdict for s in sequences]


def test_in_order_gap_duplicate_and_late_record() -> None:
    """A gap counts lost; a repeat is a duplicate; a late one is out of order and un-lost."""
    t = SequenceTracker()
    t.new_request()
    verdicts = feed(t, [1, 2, 4, 4, 6, 3, 5])
    assert verdicts == [Verdict.NEW, Verdict.NEW, Verdict.NEW, Verdict.DUPLICATE, Verdict.NEW,
                        Verdict.OUT_OF_ORDER, Verdict.OUT_OF_ORDER]
    assert (t.records, t.lost, t.duplicates, t.out_of_order) == (4, 0, 1, 2)
    assert feed(t, [3]) == [Verdict.DUPLICATE]  # already seen late: now a duplicate


def test_lost_tail_and_first_records() -> None:
    """A request of 10 whose 1st and last three never come: 4 lost."""
    t = SequenceTracker()
    t.new_request()
    feed(t, [2, 3, 4, 5, 6, 7])
    assert t.lost == 1
    assert t.finish(10) == 3
    assert t.lost == 4


def test_sequence_wraps_at_two_to_the_32() -> None:
    """0xFFFFFFFF -> 0 -> 1 is in order; skipping 0 is one lost."""
    assert ahead(0xFFFFFFFF, 0) == 1 and ahead(1, 0xFFFFFFFF) == -2
    t = SequenceTracker()
    t.new_request()
    feed(t, [0x7FFFFFFF, 0xFFFFFFFE], ft0=0)  # as if the stream had run for a week
    t.lost = 0
    feed(t, [0xFFFFFFFF, 1], ft0=10)
    assert (t.records, t.lost) == (4, 1)


def test_new_request_restarts_rdt_and_ft_going_back_is_a_reboot() -> None:
    """rdt_sequence restarts at 1 per request; ft_sequence only restarts when the box boots."""
    t = SequenceTracker()
    t.new_request()
    feed(t, [1, 2, 3], ft0=1000)
    t.new_request()
    assert not t.push(1, 1004).reboot
    t.new_request()
    acc = t.push(1, 1)
    assert acc.verdict is Verdict.NEW and acc.reboot
    assert t.reboots == 1 and t.lost == 0


def test_stragglers_of_the_last_request_are_accounted_there() -> None:
    """After a new start, a copy or a late record of the last request is not a new record."""
    t = SequenceTracker()
    t.new_request()
    for rdt in (1, 2, 4):  # 3 late, 4 will be repeated
        t.push(rdt, 10 + rdt)
    t.finish(4)
    assert t.lost == 1
    t.new_request()
    assert t.push(3, 13).verdict is Verdict.OUT_OF_ORDER  # late: its ft is in the range
    assert t.push(4, 14).verdict is Verdict.DUPLICATE  # the same (rdt, ft) pair again
    acc = t.push(1, 15)
    assert acc.verdict is Verdict.NEW and not acc.reboot
    assert (t.lost, t.out_of_order, t.duplicates, t.reboots) == (0, 1, 1, 0)
    t.new_request()
    rebooted = t.push(1, 2)  # ft far below: the box restarted
    assert rebooted.verdict is Verdict.NEW and rebooted.reboot
