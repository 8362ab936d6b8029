"""What the arm's fitted values' uncertainty does to the sponge's: its share of their 1-sigma.

The arm (its start delay, acceleration, lag) is fitted first, from the moves' timing
(:func:`~forcelearn.tools.twin.arm.fit_arm`, an identification's polled moves), and the
sponge is then fitted with those values as if exact. They are not: the lag sets how far the
tool had got at each burst, so how long the foam had relaxed, and hidden cell 15 of seed 1
(lag fitted 0.0572 +- 0.0023 s against 0.0532) put the relaxation ratio at 0.5298 +- 0.0012
against 0.5253 (+3.8 sigma), one lag-sigma moving the ratio 3 of its sigmas. Each fitted arm
value with a finite 1-sigma is moved by it either way, and the sponge's first-order response
(one Gauss-Newton step from the member's solution, ``-(J^T J)^-1 J^T dr``; the larger of the
two ends: the forward model's response to the lag is not linear) is its share; summed in
quadrature over the arm's values, added in quadrature to the sponge's 1-sigma (a
propagation of the first stage's uncertainty into the second, as
:mod:`~forcelearn.tools.twin.held` does for held sponge values).
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.bias import BiasWalk
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.problem import FirstOrder, Fitted, Problem, fitted_names


def arm_spread(fit: Fitted, train: RecordArrays, arm: dict[str, float],
               arm_sigmas: dict[str, float], reading: Reading, noise_n: float,
               walk: BiasWalk | None = None) -> dict[str, float]:
    """The arm's uncertainty's share of each fitted sponge parameter's 1-sigma (module doc).

    ``arm_sigmas``: the arm fit's 1-sigma by name; only finite, positive ones (fitted
    values, not held ones) count. Empty when none or no fitted sponge parameter.
    """
    moved = [a for a in arm if math.isfinite(arm_sigmas.get(a, math.inf))
             and arm_sigmas[a] > 0]
    if not fitted_names(fit) or not moved:
        return {}
    base = FirstOrder.at(fit, Problem(train, arm, reading, noise_n, walk))
    total = np.zeros(len(base.names))
    for name in moved:
        steps = [np.abs(base.step(Problem(train, {**arm, name: end}, reading, noise_n, walk)))
                 for end in (arm[name] - arm_sigmas[name], arm[name] + arm_sigmas[name])]
        total += np.max(steps, axis=0) ** 2
    return dict(zip(base.names, np.sqrt(total).tolist(), strict=True))
