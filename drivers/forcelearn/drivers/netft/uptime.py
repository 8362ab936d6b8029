"""A Net F/T that rebooted unseen: its sample counter is younger than the host's wait for it.

``ft_sequence`` counts the box's internal samples from power-up, 7000 per
second whatever the RDT rate (manual §10). :class:`~.sequence.SequenceTracker`
sees a reboot when that number goes back; it misses one whose new count has
already passed the old (a box that had been up a short while, then read long
after its reboot), and one before the driver's first record (nothing to
compare with). The host's clock closes both holes: a record sampled after a
request sent at host time ``t`` carries at least the count of the last record
received (at host time ``t0``) plus ``7000 × (t − t0)``; a smaller count means
the box started counting again in between. Before any record, "set software
bias" (the box was up then) is the reference, with a count of at least 0.

No socket here. The clock must be the one the box's samples follow: the
host's monotonic clock for a real box, the cell's simulated clock for an
emulated one (it runs as fast as the host goes, not at wall time).
"""

from __future__ import annotations

from forcelearn.drivers.netft.sequence import ahead

INTERNAL_RATE_HZ = 7000.0
"""The box's internal sample rate, samples/s: ``ft_sequence`` counts these (manual §10)."""
CLOCK_TOLERANCE = 1e-3
"""Relative disagreement allowed between the box's and the host's clocks (crystals are ppm)."""
SLACK_S = 0.02
"""Allowance for rounding and for a box that booted just after the reference, s."""
MAX_ELAPSED_S = 86_400.0
"""Longer than this between reads is not judged (``ft_sequence`` wraps after 7.1 days)."""


class UptimeCheck:
    """Says when a record's ``ft_sequence`` is younger than the time since the last one.

    Attributes:
        restarts: records judged to follow an unseen reboot.
    """

    def __init__(self, rate_hz: float = INTERNAL_RATE_HZ) -> None:
        self.rate_hz = float(rate_hz)
        self.restarts = 0
        self._base: tuple[float, int | None] | None = None  # (host s, ft_sequence or unknown)

    def note_bias(self, host_s: float) -> None:
        """"Set software bias" was sent at ``host_s``: the box was up then (count >= 0)."""
        if self._base is None:
            self._base = (host_s, None)

    def restarted(self, ft_sequence: int, request_s: float, received_s: float) -> bool:
        """Judge a NEW record asked for at ``request_s``, received at ``received_s`` (host s).

        True when its count grew less than the host's clock since the reference
        allows; the record becomes the next reference either way.
        """
        base, self._base = self._base, (received_s, ft_sequence)
        if base is None:
            return False
        base_s, base_ft = base
        elapsed = request_s - base_s
        if not 0.0 < elapsed < MAX_ELAPSED_S:
            return False  # sampled before the reference was taken (streaming): nothing to say
        grown = ft_sequence if base_ft is None else ahead(base_ft, ft_sequence)
        due = self.rate_hz * (elapsed * (1.0 - CLOCK_TOLERANCE) - SLACK_S)
        if grown < due:
            self.restarts += 1
            return True
        return False

    def forget(self) -> None:
        """No reference any more (a reboot handled, or the clock or the box was restored)."""
        self._base = None
