"""A bias step in contact, told from a force change by the moves the cell made.

A sensor's bias that jumps while the tool presses reads as force: nothing in
the reading tells the two apart, and a zero check needs free space. The cell
knows its moves, though. Between two consecutive readings of a trial (its
first press, then step 1, 2...) a foam pressed in by ``Δy`` mm (−Y is deeper)
changes its force by about ``−k·Δy``, ``k`` its stiffness, and it never
pulls. :class:`BiasWatch` takes the force a stiffness in
``stiffness_band_n_per_mm`` allows after the last reading (clamped at 0: the
tool may leave the foam) and calls a reading more than ``margin_n`` outside
it suspect. A reading that drops past the band as the tool eases off is not
called suspect at once: a hysteretic foam unloads along a lower branch (by up to 2 h F
after a reversal, h its loss, unknown without a probe), which a bias step read as less force
looks like; the reading before the ease-off is kept as an anchor and the next reading
pressed back to its depth or deeper is judged against it (the foam is back on its loading
branch there, a bias step is not). A trial's first press is also compared with the last trial's at
the same X and Z (within ``PRESS_DY_MM`` in Y) when no zero came between,
within ``press_margin_n``: that catches a step that came in free space. And
with ``free_y_mm`` (the retract plane, free space by the cell's
configuration) every reading at or above it must be within ``free_margin_n``
of 0: the surface probe starts each point there. A suspect reading raises
:class:`~forcelearn.errors.SensorSuspect`: the run retracts, reads free
space, zeroes there and runs the trial (or the probe) again
(:mod:`forcelearn.tools.experiments.fault_recovery`).

The defaults come from fault-free runs of the emulated example cells
(docs/on-site.md, "Bias steps in contact"): a band of 0.5 to 4 N/mm around
the sponge's 2 N/mm; the largest excess over 2,810 step pairs was 1.83 N
(the sponge's stiffness varies along Z, relaxes after a fresh press and
follows another branch when easing off), so a margin of 2.5 N; over 196
pairs of first presses, 0.36 N, so 1.2 N; over 56 probe readings at the
retract plane, 0.37 N, so 1.0 N. Those defaults fit the example sponge
only: after the surface probe the run widens them to the material it
measured (:meth:`BiasWatch.fit_to_probe`): the band and the margins scale
with the softest and stiffest points the probe fitted against the example's
(1.7 and 2.3 N/mm: a stiff part of 8 N/mm changes by 8 N over a 1 mm step,
and what a move leaves unexplained is depth, the surface between the steps'
Z), the margins grow by the branch gap a resolved hysteresis opens at the
desired force (2 h F). On the example sponge nothing changes; it never narrows
them. It cannot see a step smaller than its
margin (plus what the band leaves open) or a slow drift; a step in free
space is seen only at the next trial's first press or probe point, so the
readings of the trial it came in (after it) are kept.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from forcelearn.devices import Pose
from forcelearn.errors import SensorSuspect

STIFFNESS_BAND_N_PER_MM = (0.5, 4.0)
"""Stiffnesses a step's force change may follow, N/mm (the emulated sponge: 2 ± 15 %, worn
softer, fresh presses up to 25 % stiffer)."""
MARGIN_N = 2.5
"""Excess over the band that makes a reading suspect, N (fault-free runs: at most 1.83 N)."""
PRESS_MARGIN_N = 1.2
"""The same for a trial's first press against the last trial's at the same X and Z with no zero
between, N (fault-free runs: at most 0.36 N over 196 pairs)."""
FREE_MARGIN_N = 1.0
"""Most a reading at the retract plane (free space) may be from 0, N (fault-free: 0.37 N)."""
PRESS_DY_MM = 3.0
"""A trial's first press is compared with the last one's only this close in Y, mm (the map's
wear shift moves it a little; a tare's reading at the retract plane is far)."""
EXAMPLE_SOFTEST_N_PER_MM = 1.7
"""The softest point the example sponge's probe fits (2 N/mm - 15 %), N/mm: the defaults'
band and margins were measured there."""
EXAMPLE_STIFFEST_N_PER_MM = 2.3
"""The stiffest point the example sponge's probe fits (2 N/mm + 15 %), N/mm."""
SLACK_MM = MARGIN_N / EXAMPLE_STIFFEST_N_PER_MM
"""The margin as depth, mm: what a step's move leaves unexplained is mostly position (the
surface rising or falling between the steps' Z, the contact's spread), so on a stiffer part
the margin grows with the stiffness (an 8 N/mm part with 1 mm waviness read 2.8 N more than
the band over a 0.34 mm step, fault-free)."""
PRESS_SLACK_MM = PRESS_MARGIN_N / EXAMPLE_STIFFEST_N_PER_MM
"""The first press's margin as depth, mm."""
CONTACT_N = 1.0
"""The last reading must be at least this, N: a press from free space has no known start."""


def follows(before: tuple[str, int], now: tuple[str, int]) -> bool:
    """True when ``now`` is the next step of the trial after ``before``'s reading."""
    kind, index = now
    return kind == "step" and (before == ("approach", 0) or before == ("step", index - 1))


class BiasWatch:
    """Calls a whole burst suspect when the last step's move cannot explain its change.

    Set as the cell's :attr:`~forcelearn.cell.Cell.reading_check`.

    Attributes:
        checked: readings judged.
        suspects: readings called suspect.
        false_alarms: suspects a zero check then found the zero in place for (each widened
            the margins: :meth:`widen`).
    """

    def __init__(self, stiffness_band_n_per_mm: tuple[float, float] = STIFFNESS_BAND_N_PER_MM,
                 margin_n: float = MARGIN_N, contact_n: float = CONTACT_N,
                 press_margin_n: float = PRESS_MARGIN_N, free_y_mm: float | None = None,
                 free_margin_n: float = FREE_MARGIN_N) -> None:
        low, high = stiffness_band_n_per_mm
        if not 0.0 <= low <= high or margin_n <= 0.0 or press_margin_n <= 0.0:
            raise ValueError(f"a stiffness band {stiffness_band_n_per_mm} (0 <= low <= high) "
                             f"and a margin {margin_n} > 0 N")
        self.band = (float(low), float(high))
        self.margin_n = float(margin_n)
        self.press_margin_n = float(press_margin_n)
        self.free_y_mm = free_y_mm
        self.free_margin_n = float(free_margin_n)
        self.contact_n = float(contact_n)
        self.checked = 0
        self.suspects = 0
        self.false_alarms = 0
        self._last: tuple[tuple[str, int], float, float] | None = None  # stage, y mm, force N
        self._press: tuple[tuple[int, float, float], float, float] | None = None
        """The last trial's first press: ((zeros, x mm, z mm), y mm, force N)."""
        self._anchor: tuple[float, float] | None = None
        """The reading before an ease-off that dropped past the band: (y mm, force N), judged
        again when the tool presses back to its depth (:meth:`__call__`)."""
        self.deferred = 0
        """Ease-off drops past the band left to the press back (a foam's unloading branch)."""

    def fit_to_probe(self, stiffness_n_per_mm: Sequence[float], hysteresis_loss: float,
                     force_n: float) -> None:
        """Widen the band and margin to the material the probe measured (never narrow them).

        ``stiffness_n_per_mm``: the probe's fitted stiffness per point, N/mm;
        ``hysteresis_loss``: the resolved loss h (0 or NaN: none); ``force_n``: the
        desired force, N (the branch gap a reversal opens there is 2 h F).
        """
        stiff = [float(k) for k in stiffness_n_per_mm if math.isfinite(k) and k > 0.0]
        if stiff:
            low, high = STIFFNESS_BAND_N_PER_MM
            self.band = (min(self.band[0], low / EXAMPLE_SOFTEST_N_PER_MM * min(stiff)),
                         max(self.band[1], high / EXAMPLE_STIFFEST_N_PER_MM * max(stiff)))
            self.margin_n = max(self.margin_n, SLACK_MM * max(stiff))
            self.press_margin_n = max(self.press_margin_n, PRESS_SLACK_MM * max(stiff))
        if math.isfinite(hysteresis_loss) and hysteresis_loss > 0.0:
            gap_n = 2.0 * hysteresis_loss * abs(force_n)
            self.margin_n = max(self.margin_n, MARGIN_N + gap_n)
            self.press_margin_n = max(self.press_margin_n, PRESS_MARGIN_N + gap_n)

    def forget(self) -> None:
        """Drop the reference readings (the last one, the last trial's first press): rolled back."""
        self._last = self._press = self._anchor = None

    def widen(self, factor: float) -> None:
        """Widen both in-contact margins by ``factor`` (> 1): a zero check proved an alarm false."""
        if factor <= 1.0:
            raise ValueError(f"a widening factor > 1, not {factor}")
        self.margin_n *= factor
        self.press_margin_n *= factor
        self.false_alarms += 1

    def expected_n(self, force_n: float, dy_mm: float) -> tuple[float, float]:
        """The range of force a move of ``dy_mm`` along Y leads to from ``force_n``, N."""
        low, high = (force_n - k * dy_mm for k in self.band)
        return max(0.0, min(low, high)), max(0.0, low, high)

    def __call__(self, stage: tuple[str, int], pose: Pose | None, force_n: float,
                 zeros: int = 0) -> None:
        """Judge one whole burst's normal force (N) at the pose commanded.

        ``zeros`` counts the zeros the sensor has taken (a press is compared
        with the last trial's only if none came between).

        Raises:
            SensorSuspect: the change since the reference reading is outside the band.
        """
        if pose is None:
            self._last = None
            return
        here = (stage, float(pose.y_mm), float(force_n))
        last, self._last = self._last, here
        if self.free_y_mm is not None and here[1] >= self.free_y_mm:  # free space: reads 0
            self.checked += 1
            if abs(force_n) > self.free_margin_n:
                self._suspect(f"the force read {force_n:.2f} N at {stage[0]} {stage[1]} at the "
                              f"retract plane (y = {here[1]:.2f} mm, free space), more than "
                              f"{self.free_margin_n:g} N from 0: the zero moved")
            return
        margin = self.margin_n
        reference: tuple[float, float] | None = None  # (y mm, force N)
        anchor, eased = self._anchor, False
        if stage[0] != "step":
            self._anchor = anchor = None
        if stage == ("approach", 0):  # a trial's first press: the last trial's, same X and Z
            press, place = self._press, (zeros, float(pose.x_mm), float(pose.z_mm))
            if (press is not None and press[0] == place
                    and abs(press[1] - here[1]) <= PRESS_DY_MM):
                reference, margin = (press[1], press[2]), self.press_margin_n
            if force_n >= self.contact_n:
                self._press = (place, here[1], here[2])
        elif last is not None and follows(last[0], stage):
            reference = (last[1], last[2])
            eased = here[1] > last[1]
        if anchor is not None and here[1] <= anchor[0]:  # pressed back to the anchor's depth
            self._anchor = None
            self._judge(stage, here[1], force_n, anchor, margin)
            return
        if reference is None or reference[1] < self.contact_n:
            return
        low = self.expected_n(reference[1], here[1] - reference[0])[0]
        if eased and force_n < low - margin:  # dropped easing off: an unloading branch, or a
            self.deferred += 1  # step down; pressing back to that depth tells them apart
            if self._anchor is None:
                self._anchor = reference
            return
        if anchor is not None and force_n >= low - margin:  # between the branches: a rise
            return  # back towards the loading branch is the foam's (judged at the anchor)
        self._judge(stage, here[1], force_n, reference, margin)

    def _judge(self, stage: tuple[str, int], y_mm: float, force_n: float,
               reference: tuple[float, float], margin_n: float) -> None:
        before_y, before_n = reference
        self.checked += 1
        low, high = self.expected_n(before_n, y_mm - before_y)
        excess = max(low - force_n, force_n - high)
        if excess <= margin_n:
            return
        self._suspect(
            f"the force read {force_n:.2f} N at {stage[0]} {stage[1]} (y = {y_mm:.2f} mm), "
            f"{before_n:.2f} N before at y = {before_y:.2f} mm: a stiffness of "
            f"{self.band[0]:g} to {self.band[1]:g} N/mm gives {low:.2f} to {high:.2f} N, "
            f"{excess:.2f} N more than the {margin_n:g} N allowed: a bias step?"
        )

    def _suspect(self, what: str) -> None:
        self.suspects += 1
        self._last = self._press = self._anchor = None  # the trial starts afresh after the check
        raise SensorSuspect(
            f"{what} The run retracts, checks the zero in free space and runs the trial "
            "again; if it repeats, check the sensor's cable and temperature"
        )
