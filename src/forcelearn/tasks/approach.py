"""How finely an approach steps in: enough readings between the contact and the deepest press.

One rule for every probe that steps in towards a part until a force (the §5 surface probe,
the path task's probe pass, ``forcelearn identify``'s press). An approach in steps of ``s`` on
a part of stiffness ``k`` rises ``k s`` a step, so a press from the contact to a force
``span_n`` above it reads at most ``span_n / (k s)`` times: on a stiff part with a small force
one step passes it (8 N/mm at 5 N: a 1 mm step rises 8-10 N, the §5 probe aims 5.25 N above
its contact), and the fit of the press has one reading in contact.

The first reading in contact shows it. Its rise over the last reading in free space, over the
press-in between them, is about the part's stiffness ``k``, at least (the surface lies below
the free reading); and where it passes the contact's force by more than ``span_n /``
:data:`READINGS`, fewer than that many readings are left before the deepest press. Then the
approach backs out to that free reading and steps in again in steps of
``span_n / (READINGS x k)`` (``k`` the steepest of this approach's contacts; floor
:data:`~forcelearn.press_guard.MIN_STEP_MM`), at most :data:`REFINES` times and only while the
step shrinks to :data:`SHRINK` of the last or less. A contact that then still reaches the
deepest press's force is :class:`ApproachTooCoarse` (what to set); one under it presses on,
and the press steps no coarser than a quarter of the fine step (:meth:`FineApproach.fine_step_mm`).
The default cell never refines (its 2 N/mm sponge passes 1 N by at most 1.5 N in a 1 mm step;
its §5 probe's threshold is 7.8 N).
"""

from __future__ import annotations

from dataclasses import dataclass

from forcelearn.errors import ForcelearnError
from forcelearn.press_guard import MIN_STEP_MM

READINGS = 3
"""Readings wanted from the contact to the deepest press (a fit of two lines up without error)."""
REFINES = 4
"""Fresh approaches one contact may take (each bound on the stiffness is a lower one: a surface
met just before the reading looks soft, and the next approach meets it steeper)."""
SHRINK = 0.8
"""A fresh approach is taken only with a step at most this share of the last (a finer one
that is not finer by much would meet the same; the press then goes on from the contact)."""

PROBE_APPROACH_ADVICE = ("set [probe] approach_step_mm to {step} mm or less (a run then starts "
                         "finer), or raise [task] desired_force_n")
"""What :class:`ApproachTooCoarse` tells a run whose step is ``[probe] approach_step_mm``."""
PROBE_FLOOR_ADVICE = ("raise [task] desired_force_n or [probe] press_force_ratio, or lower "
                      "[probe] contact_force_n (the press's span)")
"""What :class:`ApproachTooCoarse` tells such a run when the finest step met it too."""


class ApproachTooCoarse(ForcelearnError):
    """An approach still meets its whole press in one step after :data:`REFINES` fresh ones."""


@dataclass
class FineApproach:
    """The step of one approach, refined at its first contact (the module docstring).

    Args:
        configured_mm: the configured step, mm (each approach starts with it: the coarse steps
            find the part, the fine ones read it).
        contact_n: the force that marks contact, N.
        span_n: the force the press rises from ``contact_n`` to its deepest reading, N.
        advice: what to set, told by :class:`ApproachTooCoarse` (``{step}``: the step it
            would take, mm).
        floor_advice: what to set when even :data:`~forcelearn.press_guard.MIN_STEP_MM` met
            it (no step reads the press twice): a wider span.
        widest_span_n: a press free to end deeper (``forcelearn identify``'s: it only needs
            readings in contact) widens :attr:`span_n` up to this, N, where no finer step is
            left, to the span that gives :data:`READINGS` readings in contact at the step in
            use;
            0 (a probe whose deepest force is the task's): never widened.
    """

    configured_mm: float
    contact_n: float
    span_n: float
    advice: str
    floor_advice: str = PROBE_FLOOR_ADVICE
    widest_span_n: float = 0.0
    step_mm: float = 0.0
    """The step in use, mm (:meth:`start` sets the configured one)."""
    refines: int = 0
    """Fresh approaches taken towards this contact."""
    stiffness_n_per_mm: float = 0.0
    """The steepest first contact that asked for a fresh approach (about the part's stiffness,
    at least: the surface lies below the free reading), N/mm; 0 while none did. Kept over the
    approaches of one part (the press's steps use it, :meth:`fine_step_mm`)."""
    _point_n_per_mm: float = 0.0
    """The same over this approach's contacts: its steps come from it (one noisy fine pair at
    another point must not shrink every later step)."""

    def __post_init__(self) -> None:
        self.start()

    def start(self) -> None:
        """A new approach (another point of the same part): the configured step, no refines."""
        self.step_mm = self.configured_mm
        self.refines = 0
        self._point_n_per_mm = 0.0

    def fine_step_mm(self) -> float:
        """The step the rule gives for the stiffness seen (:attr:`step_mm` if finer), mm.

        A press that met its contact in a coarse step on a part known stiff (an earlier
        point's approach) steps no coarser than this (else a 0.25 mm floor on 15 N/mm at
        3 N passed the whole press in one step).
        """
        if self.stiffness_n_per_mm <= 0.0 or self.span_n <= 0.0:
            return self.step_mm
        fine = max(self.span_n / (READINGS * self.stiffness_n_per_mm), MIN_STEP_MM)
        return min(self.step_mm, fine)

    def again(self, force_n: float, free_n: float, pressed_mm: float, where: str = "") -> bool:
        """A first contact: ``force_n`` read ``pressed_mm`` mm past a free reading of ``free_n``.

        True: back out to that free reading and approach again in :attr:`step_mm` (now finer).
        False: go on pressing from here: it passed the contact's force by at most a third of the
        span, or no finer step is left to take and it is still under the deepest press's force
        (the press then steps from the stiffness seen), or the span was widened (within
        :attr:`widest_span_n`) so that it is.

        Raises:
            ApproachTooCoarse: it reached the deepest press's force in one step and no finer
                step is left (:data:`REFINES` fresh approaches taken, or the step is at
                :data:`~forcelearn.press_guard.MIN_STEP_MM`), and no span within
                :attr:`widest_span_n` reads the press :data:`READINGS` times.
        """
        over_n = force_n - self.contact_n
        if pressed_mm <= 0.0 or self.span_n <= 0.0 or READINGS * over_n <= self.span_n:
            return False
        seen = (force_n - free_n) / pressed_mm
        self._point_n_per_mm = max(self._point_n_per_mm, seen)
        self.stiffness_n_per_mm = max(self.stiffness_n_per_mm, seen)
        step = max(self.span_n / (READINGS * self._point_n_per_mm), MIN_STEP_MM)
        if self.refines < REFINES and step < SHRINK * self.step_mm:
            self.refines += 1
            self.step_mm = step
            return True
        if over_n < self.span_n:
            return False
        # this reading and READINGS - 1 more steps of seen x step_mm, the last ending the press
        # half a step early (noise may not cut it short of its READINGS readings)
        wider = over_n + (READINGS - 1.5) * seen * self.step_mm
        if wider <= self.widest_span_n:
            self.span_n = wider
            return False
        at_floor = self.step_mm <= MIN_STEP_MM
        what = (f"even the finest step, {MIN_STEP_MM:g} mm, passes it: " + self.floor_advice
                if at_floor else self.advice.format(step=f"{step:.3g}"))
        raise ApproachTooCoarse(
            f"the approach{where} met {force_n:.2f} N {pressed_mm:.3g} mm past a free reading "
            f"({seen:.3g} N/mm) after {self.refines} finer approaches: its press from the "
            f"contact ({self.contact_n:g} N) to {self.contact_n + self.span_n:.2f} N has one "
            f"reading (a stiff part with a small force); {what}"
            + (f" (a press widened to read it {READINGS} times would end {wider:.2f} N over the "
               f"contact, past the {self.widest_span_n:.2f} N allowed)"
               if self.widest_span_n > 0 else ""))
