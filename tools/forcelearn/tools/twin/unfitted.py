"""A mechanism the fitted family leaves out that the records show: its share of the 1-sigma.

A tool reading along the surface's normal sees the roller's friction only through the
surface's slope, so the friction members are not fitted for it
(:data:`~forcelearn.tools.twin.choice.FRICTION_READING_MIN`). Where the cell has a friction,
the chosen member's other values make up for it, most of all the waviness (the slope's wave
carries the friction's share of the reading): hidden cell 16 of seed 2 (friction 0.35) put
the waviness's wavelength at 81.20 +- 0.25 mm against 80 (+4.7 sigma); refitted with the
friction free as well, 79.88 (the friction 0.347 +- 0.013, the cost 6,585 -> 2,089).

Each left-out mechanism's amplitude is freed beside the chosen member's values, refitted
from its solution; when the records want it (the cost falls by more than the BIC's penalty
for one parameter, ``log(n) / 2`` in units of the fit's own residual variance, and the
amplitude is ``SHOWN_SIGMAS`` of its 1-sigma from 0), the shift
of each checked value (the shapes along the path and the static force law,
:data:`~forcelearn.tools.twin.experiments.CHECKED`) is its share of the 1-sigma: the
records do not rule that mechanism out, and the values move with it. Nothing when they do
not want it (a cell without friction: its fitted amplitude stays near 0).
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.bias import BiasWalk
from forcelearn.tools.twin.experiments import CHECKED
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import FRICTION, Member
from forcelearn.tools.twin.problem import Fitted, Problem

REFIT_EVALUATIONS = 40
"""At most this many evaluations per parameter of the refit with the mechanism freed."""
SHOWN_SIGMAS = 3.0
"""...and its fitted amplitude is this many of its own (sandwich) 1-sigma from 0. The default
cell (no friction; 300 trials, seed 0) fits a friction of 0.016 +- 0.007 that lowers the
cost by 5.3 residual variances (the penalty 4.4): what it absorbs is not a friction."""
START_SHARE = 0.025
"""The freed amplitude starts at this share of its range (0 sits on its bound)."""


def unfitted_spread(fit: Fitted, members: tuple[Member, ...], train: RecordArrays,
                    arm: dict[str, float], reading: Reading, noise_n: float,
                    walk: BiasWalk | None = None) -> dict[str, float]:
    """The left-out mechanisms' share of each checked value's 1-sigma (module docstring).

    ``members``: the family that was fitted; a mechanism counts as left out when no member
    of it fits its amplitude. Empty when none is left out or the records do not want it.
    """
    fitted_free = {n for m in members for n in m.free}
    left_out = [p for p in (FRICTION,) if p.name not in fitted_free]
    names = [n for n in fit.member.free if n not in dict(fit.member.fixed) and n not in fit.held]
    if not left_out or not names:
        return {}
    problem = Problem(train, arm, reading, noise_n, walk)
    r0 = problem.residuals(problem.predicted([], dict(fit.values), np.zeros(0)))
    cost0 = 0.5 * float(r0 @ r0)
    n = int(np.count_nonzero(r0))
    if n <= len(names) + 1 or cost0 <= 0:
        return {}
    variance = 2 * cost0 / (n - len(names))  # the fit's residual variance per residual
    total = dict.fromkeys(names, 0.0)
    for param in left_out:
        start = {**fit.values, param.name: param.low + START_SHARE * (param.high - param.low)}
        freed = [*names, param.name]
        x, result = problem.solve(freed, start, max_nfev=REFIT_EVALUATIONS * len(freed))
        amplitude = abs(float(x[-1]) - param.low)
        seen = amplitude > SHOWN_SIGMAS * float(problem.sigmas(result.jac, result.fun)[-1])
        if not (seen and (cost0 - float(result.cost)) / variance > 0.5 * math.log(n)):
            continue
        for name, value in zip(names, x.tolist(), strict=False):
            total[name] += (value - fit.values[name]) ** 2
    return {name: math.sqrt(v) for name, v in total.items() if name in CHECKED and v > 0}
