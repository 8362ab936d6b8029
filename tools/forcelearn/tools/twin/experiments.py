"""Do the fitted records' experiments agree? Their disagreement's share of each 1-sigma.

A run's records hold more than one experiment: the learner's control steps, the surface
probe (a few presses of the fresh foam at places along the path) and, with ``forcelearn
identify``, the identification's presses, holds and cycles. Each is fitted with one forward
model; where that model differs from the cell's (a relaxation across the probe's dwells, the
identification's holds), each experiment pulls the shared values its own way, and the fit
settles where the weights put it: the sandwich, the trial-block jackknife and the probe's
delete-one point never see it (the probe and the identification stay in every block's refit,
and one probe point is a seventh of the probe). Hidden cell 19 of seed 2: the probe pulled
the stiffness's wavelength to 122.37 +- 0.44 mm (truth 120; without the probe 117.4) and the
waviness's to 79.28 +- 0.20 (truth 80); hidden cell 14 of seed 2: the identification pulled
the stiffness to 2.319 +- 0.006 N/mm (truth 2.294; without it 2.308).

Each such experiment is left out in turn (a few Gauss-Newton steps from the member's
solution, :meth:`~forcelearn.tools.twin.problem.Problem.refits`): the shift ``d`` of each
value against what the smaller records' own uncertainty explains (a Hausman test: for an
efficient fit ``var(d) = var(without) - var(all)``) leaves an excess
``sqrt(max(0, d^2 - (s_without^2 - s_all^2)))``, the experiments' disagreement, added in
quadrature to the value's 1-sigma. A value the rest cannot determine without the
experiment (its ``s_without`` large) gets no excess: its shift is the rest's ignorance.
Only the values every experiment measures alike are checked (``CHECKED``: the shapes along
the path and the static force law; not the fresh surface's height and tilt, which the probe
alone sees unworn): the relaxation, the wear and the hysteresis are seen through
each experiment's own timing and history, the identification's holds made to show the
relaxation the run's steps barely do (docs/twin-fit.md, "Determined or not").
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.tools.experiments.records import PROBE_TRIAL
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.bias import BiasWalk
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.identify import IDENTIFY_TRIAL
from forcelearn.tools.twin.params import BY_NAME
from forcelearn.tools.twin.problem import Fitted, Problem, fitted_names

EXPERIMENTS = {"surface probe": PROBE_TRIAL, "identification": IDENTIFY_TRIAL}
"""The experiments besides the control steps, by the trial number their rows carry."""
CHECKED = frozenset({"waviness_mm", "waviness_wavelength_mm", "stiffness_n_per_mm",
                     "stiffness_variation", "stiffness_wavelength_mm", "stiffening_exponent"})
"""The values every experiment measures alike (a press at a place and a depth): the shapes
along the path and the force law's static part. Not the fresh surface's height and tilt
(contact, slope): the probe is what measures them, the steps see the worn surface only, its
set fitted between (without the probe the contact moved 0.1-0.2 mm on hidden cells whose
contact was within 2 sigma of the truth). Nor the values seen through each experiment's own
timing or history (a relaxation through the identification's holds, the probe's dwells and the
steps' pace; a wear through the passes; a hysteresis through the way in and out), where the
rest of the records without one of them sees another part, not the same value again."""
LEAVE_OUT_STEPS = 3
"""Gauss-Newton steps of each refit from the member's solution."""


def experiment_spread(fit: Fitted, train: RecordArrays, arm: dict[str, float],
                      reading: Reading, noise_n: float, walk: BiasWalk | None = None
                      ) -> dict[str, float]:
    """The experiments' disagreement's share of each fitted parameter's 1-sigma (module doc).

    Summed in quadrature over the experiments the records hold besides the control steps;
    empty when they hold none, or no other records to refit on.
    """
    names = fitted_names(fit)
    checked = [i for i, n in enumerate(names) if n in CHECKED]
    present = {label: trial for label, trial in EXPERIMENTS.items()
               if (train.trial == trial).any()}
    rest = ~np.isin(train.trial, list(present.values()))
    if not names or not present or not (train.has_burst & rest[:, None]).any():
        return {}
    problem = Problem(train, arm, reading, noise_n, walk)
    masks = [np.broadcast_to((train.trial != trial)[:, None], problem.use.shape)
             for trial in present.values()]
    x0 = np.array([fit.values[n] for n in names])
    low = np.array([BY_NAME[n].low for n in names])
    high = np.array([BY_NAME[n].high for n in names])

    def predicted(x: np.ndarray) -> np.ndarray:
        return problem.predicted(names, fit.values, x)

    def sigmas(x: np.ndarray, keep: np.ndarray | None) -> np.ndarray:
        # the sandwich at ``x``, the fit's solution on ``keep``'s bursts (its scores sum to 0)
        r0, jac = problem.jacobian(predicted, x, keep, low, high)
        return problem.sigmas(jac, r0)

    s_all = sigmas(x0, None)
    moved = problem.refits(names, fit.values, masks, [LEAVE_OUT_STEPS] * len(masks))
    total = np.zeros(len(names))
    for keep, x in zip(masks, moved, strict=True):
        with np.errstate(invalid="ignore"):  # inf - inf: a parameter loose either way
            explained = np.maximum(0.0, np.nan_to_num(sigmas(x, keep) ** 2 - s_all**2,
                                                      nan=np.inf))
        excess = np.sqrt(np.maximum(0.0, (x - x0) ** 2 - explained))
        total += excess**2
    return {names[i]: float(math.sqrt(total[i])) for i in checked
            if 0 < total[i] < math.inf}

