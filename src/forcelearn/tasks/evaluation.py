"""The evaluation a force task gives the learner: r, the failure rule and its scale.

The contract between a task and the learner (docs/tasks.md):

* r is dimensionless, smaller is better; 0 is the desired force exactly and
  r = 1 is the edge of the task's **tolerance**: the learner's search width
  σ = s(r̂) saturates there (``forcelearn.learning.exploration``), and its
  initial prediction r̂ (0.5) is half of it.
* a step with r > 1 **fails** (:data:`FAILURE_R`): the trial ends and the task
  returns to its start; so does a step the cell's safety stopped (the force
  limit), whatever its force, and it is learned as r = :data:`SAFETY_R`.
* the **scale** between newtons and r is the tolerance: r = |F − F_d| / tolerance.
  Whatever else speaks in tolerances (the warm start's r̂, the probe's
  predicted error of a map, the baselines' step size and missing steps)
  converts through :meth:`ForceEvaluation.ratio` and :meth:`ForceEvaluation.error_n`,
  so a task kind that changes its evaluation changes it here, once.

The §5 surface task evaluates with it, and so will the path task.
"""

from __future__ import annotations

from dataclasses import dataclass

FAILURE_R = 1.0
"""A step whose r passes this fails (the edge of the tolerance)."""
SAFETY_R = 2.0
"""Evaluation given to a step stopped by the force limit (a failure, learned as one)."""


@dataclass(frozen=True)
class Evaluation:
    """What one measured force is worth to the learner."""

    r: float
    """The evaluation (dimensionless, >= 0; > 1 is a failure)."""
    failed: bool
    """The step fails (r > 1, or the safety stopped it)."""
    force_error_n: float
    """Measured minus desired force, N."""


@dataclass(frozen=True)
class ForceEvaluation:
    """r = |F − F_d| / tolerance, failure above 1: the §5 evaluation (forces in N)."""

    desired_force_n: float
    """F_d, N."""
    tolerance_n: float
    """The force error at which r = 1, N."""

    def ratio(self, error_n: float) -> float:
        """A force error (N) in tolerances: the r it would give."""
        return abs(error_n) / self.tolerance_n

    def error_n(self, r: float) -> float:
        """The force error (N) that gives evaluation ``r``."""
        return r * self.tolerance_n

    def evaluate(self, force_n: float, limit_hit: bool = False) -> Evaluation:
        """Evaluate a measured force (N); ``limit_hit``: the safety stopped the step."""
        error = force_n - self.desired_force_n
        r = SAFETY_R if limit_hit else self.ratio(error)
        return Evaluation(r, r > FAILURE_R or limit_hit, error)
