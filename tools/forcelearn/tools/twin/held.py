"""What a held parameter's ignorance does to the fitted ones: its share of their 1-sigma.

A scale the records leave loose (a wear's time constant in passes, a relaxation's time)
is held at the base config's value and the rest refitted
(:func:`~forcelearn.tools.twin.fit.fit_member`). The fitted values then hold only if that
value is right: a set that sets in over 100 passes trades with the fresh surface's
height, and holding it at 100 where the cell's is 110 moved hidden cell 4's contact
3.1 sigma (0.034 mm, the sigma 0.011 mm) off the truth. The held value is not known
better than the records say (its 1-sigma when it was last fitted, at least a factor
``HELD_FACTOR`` either way when that is wider than the value): each fitted parameter is
refitted with each held one at either end of that range; the largest move per held
parameter, summed in quadrature over them, is the held parameters' share of its 1-sigma
(a model-error term the Jacobian and the resampling cannot see, as they move only what
is fitted).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.bias import BiasWalk
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import BY_NAME
from forcelearn.tools.twin.problem import Fitted, Problem


class HeldFit(Fitted, Protocol):
    """What :func:`held_spread` reads of a fitted member (``fit.MemberFit`` has these)."""

    sigmas: dict[str, float]

HELD_FACTOR = 2.0
"""A held value is taken as known to within this factor either way, at most."""
HELD_STEPS = 3
"""Gauss-Newton steps of each refit from the member's solution."""


def held_range(name: str, value: float, sigma: float) -> tuple[float, float]:
    """The ends of the range a held ``value`` (1-sigma ``sigma`` when last fitted) spans."""
    param = BY_NAME[name]
    low, high = value / HELD_FACTOR, value * HELD_FACTOR
    if math.isfinite(sigma) and sigma < value - low:
        low, high = value - sigma, value + sigma
    return max(low, param.low), min(high, param.high)


def held_spread(fit: HeldFit, train: RecordArrays, arm: dict[str, float], reading: Reading,
                noise_n: float, walk: BiasWalk | None = None) -> dict[str, float]:
    """The held parameters' share of each fitted parameter's 1-sigma (module docstring)."""
    names = [n for n in fit.member.free if n not in dict(fit.member.fixed) and n not in fit.held]
    held = [n for n in fit.held if n in fit.values and fit.values[n] > 0]
    if not names or not held:
        return {}
    problem = Problem(train, arm, reading, noise_n, walk)
    keep = np.ones(problem.use.shape, bool)
    total = np.zeros(len(names))
    x0 = np.array([fit.values[n] for n in names])
    for name in held:
        moves = []
        for end in held_range(name, fit.values[name], fit.sigmas.get(name, math.inf)):
            moved = problem.refits(names, {**fit.values, name: end}, [keep], [HELD_STEPS])[0]
            moves.append(np.abs(moved - x0))
        total += np.max(moves, axis=0) ** 2
    return dict(zip(names, np.sqrt(total).tolist(), strict=True))
