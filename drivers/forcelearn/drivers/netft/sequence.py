"""Pure accounting of RDT sequence numbers: lost, duplicated, out-of-order records, reboots.

UDP neither retransmits nor keeps order. The box numbers the records of each
request 1, 2, 3... (``rdt_sequence``, u32, wraps) and stamps each with its
internal sample number (``ft_sequence``, u32, restarts when the box boots).
:class:`SequenceTracker` is fed the records of one request in arrival order:

=====================  ==============================================  =========
arrival                counted as                                      delivered
=====================  ==============================================  =========
next expected          ``records``                                     yes
ahead by k + 1         ``lost += k`` (the k skipped), ``records``      yes
already seen           ``duplicates``                                  no
older, not yet seen    ``out_of_order``, ``lost -= 1`` (it did come)   no
=====================  ==============================================  =========

Late records are dropped, as the reference driver (netft_utils) does: the host
has moved past them. So ``lost`` counts records that never arrived. A tail
lost at the end of a finite request is added by :meth:`SequenceTracker.finish`.

Requests overlap on the wire: a late or repeated record of the last request
may arrive after the next start was sent, with an ``rdt_sequence`` that the
new request also uses. ``ft_sequence`` tells them apart: the box's sample
number only grows (it counts at the box's internal rate, streaming or not),
so a record whose (rdt, ft) pair was seen in the last request is a copy, and
one the last request lacked whose ``ft_sequence`` lies in its range is a late
one; both are accounted there. Any other ``ft_sequence`` that goes back marks
a reboot (the box lost its software bias). A record delayed past a whole
request would be read as a reboot (never seen on loopback; a network would
have to hold a datagram for a whole request). No clock and no socket here.
"""

from __future__ import annotations

import enum
from collections import deque
from dataclasses import dataclass

from forcelearn.protocols.netft import SEQUENCE_MODULUS

HALF = SEQUENCE_MODULUS // 2
SEEN_WINDOW = 4096
"""Sequences remembered to tell a late record from a duplicate."""


class Verdict(enum.Enum):
    """What a record is, by its sequence number."""

    NEW = "new"
    DUPLICATE = "duplicate"
    OUT_OF_ORDER = "out_of_order"


@dataclass(frozen=True, slots=True)
class Accounted:
    """The verdict on one record; ``lost_before`` records were skipped just before a NEW one."""

    verdict: Verdict
    lost_before: int = 0
    reboot: bool = False


def ahead(previous: int, current: int) -> int:
    """Signed distance from ``previous`` to ``current`` on the u32 circle (-2**31..2**31-1)."""
    diff = (current - previous) % SEQUENCE_MODULUS
    return diff - SEQUENCE_MODULUS if diff >= HALF else diff


@dataclass
class _Request:
    """What is kept of the last request to account for its stragglers."""

    pairs: dict[int, int]  # rdt_sequence -> ft_sequence
    last_rdt: int
    ft_min: int
    ft_max: int


class SequenceTracker:
    """Count records by ``rdt_sequence`` over requests, and reboots by ``ft_sequence``.

    Attributes:
        records: records delivered (NEW).
        lost: records skipped and never seen since.
        duplicates: records received twice (the copy dropped).
        out_of_order: records that arrived after a later one (dropped).
        reboots: times ``ft_sequence`` went back (the box restarted).
    """

    def __init__(self) -> None:
        self.records = 0
        self.lost = 0
        self.duplicates = 0
        self.out_of_order = 0
        self.reboots = 0
        self._last_rdt = 0
        self._last_ft: int | None = None
        self._ft_min: int | None = None  # first ft_sequence delivered in this request
        self._previous: _Request | None = None
        self._seen: dict[int, int] = {}  # rdt_sequence -> ft_sequence, this request
        self._seen_order: deque[int] = deque()

    @property
    def last_rdt_sequence(self) -> int:
        """The highest ``rdt_sequence`` delivered in this request (0 before the first)."""
        return self._last_rdt

    def new_request(self) -> None:
        """A start request was sent: the box numbers its records from 1 again."""
        if self._ft_min is not None and self._last_ft is not None:
            self._previous = _Request(self._seen, self._last_rdt, self._ft_min, self._last_ft)
        self._last_rdt = 0
        self._ft_min = None
        self._seen = {}
        self._seen_order = deque()

    def push(self, rdt_sequence: int, ft_sequence: int) -> Accounted:
        """Account one record, in arrival order."""
        prev = self._previous
        if prev is not None and self._is_straggler(prev, rdt_sequence, ft_sequence):
            return self._straggler(prev, rdt_sequence, ft_sequence)
        step = ahead(self._last_rdt, rdt_sequence)
        if step <= 0:
            if step == 0 or rdt_sequence in self._seen:
                self.duplicates += 1
                return Accounted(Verdict.DUPLICATE)
            self._remember(rdt_sequence, ft_sequence)
            self.out_of_order += 1
            self.lost -= 1
            return Accounted(Verdict.OUT_OF_ORDER)
        reboot = self._last_ft is not None and ahead(self._last_ft, ft_sequence) < 0
        if reboot:
            self.reboots += 1
            self._previous = None
        if self._ft_min is None:
            self._ft_min = ft_sequence
        self._last_ft = ft_sequence
        self._remember(rdt_sequence, ft_sequence)
        self._last_rdt = rdt_sequence
        self.records += 1
        self.lost += step - 1
        return Accounted(Verdict.NEW, step - 1, reboot)

    @staticmethod
    def _is_straggler(prev: _Request, rdt_sequence: int, ft_sequence: int) -> bool:
        """Does this record belong to the last request (a copy, or late)?"""
        if rdt_sequence in prev.pairs:
            return prev.pairs[rdt_sequence] == ft_sequence
        return ahead(rdt_sequence, prev.last_rdt) >= 0 and (
            0 <= ahead(prev.ft_min, ft_sequence) <= ahead(prev.ft_min, prev.ft_max)
        )

    def _straggler(self, prev: _Request, rdt_sequence: int, ft_sequence: int) -> Accounted:
        """A record of the last request arriving during this one: a copy, or a late one."""
        if rdt_sequence in prev.pairs:
            self.duplicates += 1
            return Accounted(Verdict.DUPLICATE)
        prev.pairs[rdt_sequence] = ft_sequence
        self.out_of_order += 1
        self.lost -= 1
        return Accounted(Verdict.OUT_OF_ORDER)

    def finish(self, expected_last: int) -> int:
        """End a finite request of ``expected_last`` records; count and return its lost tail."""
        tail = max(0, ahead(self._last_rdt, expected_last))
        self.lost += tail
        self._last_rdt = expected_last
        return tail

    def forget_ft(self) -> None:
        """Forget the last ``ft_sequence`` (after a reboot has been handled)."""
        self._last_ft = None
        self._ft_min = None
        self._previous = None

    def _remember(self, rdt_sequence: int, ft_sequence: int) -> None:
        self._seen[rdt_sequence] = ft_sequence
        self._seen_order.append(rdt_sequence)
        if len(self._seen_order) > SEEN_WINDOW:
            self._seen.pop(self._seen_order.popleft(), None)
