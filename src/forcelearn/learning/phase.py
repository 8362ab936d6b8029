"""The phase schedule: generalized learning until the global criterion, then specialized.

The global criterion (paper §3-4) is N consecutive successful trials; a failed
trial resets the count. Once specialized, the learner stays specialized.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Phase(enum.IntEnum):
    """Which learning rule of paper §3 is in force."""

    GENERALIZED = 0
    """Eq. (2) on the input box and eq. (3) on its neighbourhood."""
    SPECIALIZED = 1
    """Eq. (2) on the input box only."""


@dataclass
class PhaseSchedule:
    """Counts trials and switches phase when the global criterion holds.

    Args:
        success_trials: N, consecutive successful trials that end the generalized phase.
        phase: the phase to start in.
    """

    success_trials: int = 10
    phase: Phase = Phase.GENERALIZED
    consecutive_successes: int = 0
    trials: int = 0
    switch_trial: int | None = None
    """Index (0-based) of the trial whose success met the criterion; None until then."""

    def end_trial(self, success: bool) -> bool:
        """Record a finished trial; return True when this trial switched the phase."""
        index = self.trials
        self.trials += 1
        self.consecutive_successes = self.consecutive_successes + 1 if success else 0
        if self.phase is Phase.GENERALIZED and self.consecutive_successes >= self.success_trials:
            self.phase = Phase.SPECIALIZED
            self.switch_trial = index
            return True
        return False
