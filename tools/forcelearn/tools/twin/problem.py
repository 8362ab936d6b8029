"""The sponge fit's least-squares problem and its resampled uncertainty (the jackknife).

:class:`Problem` holds a run's fitted trials, the arm and the sensor's bias walk, and
gives the weighted residuals of a member's free parameters; :func:`jackknife` the
resampled 1-sigma of a fitted member (docs/twin-fit.md, "Determined or not").
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Protocol

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

from forcelearn.emulators.physics.sponge_law import SpongeParams
from forcelearn.tools.experiments.records import PROBE_TRIAL
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.bias import BiasWalk
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import BY_NAME, Member
from forcelearn.tools.twin.rowgroups import GroupedForward
from forcelearn.tools.twin.uncertainty import largest_sigmas

BURST_FLOOR_N = 0.02
"""Floor of a burst mean's expected scatter in the weights, N."""
JACKKNIFE_BLOCKS = 4
"""Contiguous blocks of the fitted trials left out in turn to check the chosen member."""
BLOCK_STEPS = 1
"""Gauss-Newton steps of a block-jackknife refit from the member's solution: one, the
first-order change when a quarter of the trials is left out (on the default run's 300
trials it equals the converged refit to 1e-4 mm and 1e-5 N/mm)."""
HALF_STEPS = 3
"""...of a force-half refit: the high half alone moves the contact far (on that run
+0.284 mm after one step, 0.120, 0.094 after three, 0.089 converged)."""
STEP_HALVINGS = 10
"""A refit's Gauss-Newton step that raises its bursts' cost is halved up to this many times
(then the refit stays where it is)."""
EXTRA_STEPS = 3
"""Steps a refit may take beyond its count when some were halved."""
MIN_PROBE_POINTS = 4
"""The surface probe's points are left out one at a time when it pressed at least this many."""
COST_RESOLUTION = 1e-3
"""A least-squares step that lowers the cost (half the chi-square: units of log-likelihood) by
less than this ends the fit (:meth:`Problem.solve`): such a change is no information, and
near a minimum the values are then within ``sqrt(2 x 1e-3)`` ~ 0.05 of their Jacobian 1-sigma.
Along a valley the records do not determine (a wear's amplitude and its time constant both
growing at one initial rate) the default relative tolerance (1e-8 of the cost) crawled:
hidden cell 15 of seed 4's hysteretic member, from the nonlinear member's solution, lowered
its cost 3070.89 -> 3048.60 in 100 steps, then by 0.0004-0.0007 a step (3048.40 after 350,
the softening 0.17 -> 0.75 and its time constant 150 -> 755 passes, their ratio kept) towards
its limit of 1,600 evaluations (489 s of CPU); the time constant was then held at the base
value anyway (:func:`~.fit.fit_member`). A member that misfits (half its chi-square ``F``
above its residuals' count ``m`` over 2) is resolved as a likelihood whose noise scale is
fitted too: a unit of it is a change of ``2 F / m`` in the cost (:func:`resolution_ftol`);
that cell's linear-elastic member (cost 191,450 over 2,938 residuals) crawled to its limit
of 1,100 evaluations (84 s of CPU) by steps above 1e-3."""
FTOL = 1e-8
"""...and never stops sooner than :func:`scipy.optimize.least_squares`' default relative
tolerance would (a cost above ``COST_RESOLUTION / FTOL``)."""


def burst_weights(data: RecordArrays, noise_n: float) -> np.ndarray:
    """1 / expected scatter of each burst mean (T, M); 0 where no burst."""
    noise = noise_n if math.isfinite(noise_n) else 0.0
    spread = np.sqrt(noise**2 / np.maximum(data.count, 1.0) + BURST_FLOOR_N**2)
    return np.where(data.has_burst, 1.0 / spread, 0.0)


class Problem:
    """The weighted residuals of the train trials' bursts for a member's free parameters."""

    def __init__(self, train: RecordArrays, arm: dict[str, float], reading: Reading,
                 noise_n: float, walk: BiasWalk | None = None) -> None:
        self.train, self.arm, self.reading, self.walk = train, arm, reading, walk
        self.weights = burst_weights(train, noise_n)
        self.use = train.has_burst
        self.groups = (np.broadcast_to(train.trial[:, None], self.use.shape)[self.use]
                       if walk is None else walk.groups())
        rows = self.use if walk is None else walk.train.segment >= 0
        row_of, places = np.nonzero(rows)  # places: the burst's step in its trial (on the path)
        self.places = np.concatenate([places, -1 - np.arange(self.groups.size - places.size)])
        # each row its own group (the probe's points apart: each zeroes on its own read); a
        # walk term with its segment's row
        segment_row = np.zeros(0, int)
        if walk is not None and self.groups.size > places.size:
            segment_row = np.zeros(walk.train.size, int)
            segment_row[walk.train.segment[rows]] = row_of
        self.rows = np.concatenate([row_of, segment_row[:self.groups.size - places.size]])
        self.forward = GroupedForward(train, arm)

    def predicted(self, names: list[str], frozen: dict[str, float], x: np.ndarray
                  ) -> np.ndarray:
        """The burst means (T, M) of the sponge ``frozen`` with ``names`` at ``x``, N."""
        sponge = SpongeParams.unchecked({**frozen, **dict(zip(names, x.tolist(), strict=True))})
        return self.forward.predict(sponge, self.reading)

    def residuals(self, predicted: np.ndarray, keep: np.ndarray | None = None) -> np.ndarray:
        """The weighted residual vector of ``predicted`` (only ``keep``'s bursts count)."""
        if self.walk is not None:  # the sensor's bias, profiled out (twin/bias.py)
            return self.walk.residuals(predicted - self.train.mean_n, keep)
        # the others weigh 0 (as the walk's do): one entry per fitted burst, so the
        # uncertainty's groups stay aligned
        weights = self.weights if keep is None else np.where(keep, self.weights, 0.0)
        error: np.ndarray = ((predicted - self.train.mean_n) * weights)[self.use]
        return error

    def sigmas(self, jacobian: np.ndarray, residuals: np.ndarray) -> np.ndarray:
        """1-sigma of the fitted parameters: the sandwich's largest over four groupings.

        Residuals grouped by trial (the sensor's drift, what a pass misses), by row (a trial,
        or one point of the surface probe: each point zeroes on its own free-space read, so
        its presses share that zero's error), by the step of the trial (a place on the path
        every trial passes: what the model misses there recurs on each pass), and each alone
        (:func:`~.uncertainty.largest_sigmas`). On the default run of 300 trials (seed 4) the
        trial grouping put the stiffness at 1.9960 +- 0.0006, the other two at +- 0.0017; the
        five seeds scatter by 0.0018. The probe as one group (its few points carry half of
        what fixes the surface's height and shape, and one group's score the fit all but
        zeroes) put seed 4's waviness at 0.9879 +- 0.0039 (-3.1 sigma); by point, +- 0.0044;
        the five seeds' waviness scatters by 0.0071. The biases profiled out count against
        the residuals' degrees of freedom (:attr:`~.bias.BiasWalk.profiled`).
        """
        nuisance = self.walk.profiled if self.walk is not None else 0
        return largest_sigmas(jacobian, residuals, [self.groups, self.rows, self.places, None],
                              nuisance)

    def solve(self, names: list[str], values: dict[str, float], keep: np.ndarray | None = None,
              max_nfev: int | None = None) -> tuple[np.ndarray, OptimizeResult]:
        """Least squares over ``names`` from ``values`` (the rest frozen).

        ``keep`` (trials, moves) bool: fit only those bursts.
        """
        low, high = _bounds(names)
        x0 = np.clip(np.array([values[n] for n in names]), low + 1e-6 * (high - low),
                     high - 1e-6 * (high - low))
        frozen = dict(values)

        def residuals(x: np.ndarray) -> np.ndarray:
            return self.residuals(self.predicted(names, frozen, x), keep)

        start = residuals(x0)
        result = least_squares(residuals, x0, bounds=(low, high), x_scale="jac", method="trf",
                               ftol=resolution_ftol(half_square(start), start.size),
                               max_nfev=max_nfev or 100 * len(names))
        return np.asarray(result.x), result

    def refits(self, names: list[str], values: dict[str, float], masks: list[np.ndarray],
               steps: list[int]) -> np.ndarray:
        """``names`` refitted from ``values`` on each mask's bursts, (len(masks), len(names)).

        ``steps[k]`` Gauss-Newton steps for mask ``k`` from the full fit's solution, each
        with a forward-difference Jacobian; the first step's predictions (one per parameter,
        at the solution) serve every mask, only the walk's profile is redone per mask. A
        step that raises the mask's cost is halved until it lowers it (``STEP_HALVINGS``;
        a halved step does not count, up to ``EXTRA_STEPS`` more: a leverage point left out
        moved the slope 0.00032 in one halved step, 0.00064 converged):
        where the member fits loose parameters (a wear's time constant of 990 passes), the
        full step along their nearly flat directions left the linear model's reach (hidden
        cell 25 of seed 11: 11 of 13 refits ended above the cost they started from, one at
        697,896 from 948, and the stiffening exponent's spread, 0.23 for a 1.54 exponent,
        vetoed the member that predicts the cell).
        """
        low, high = _bounds(names)
        x0 = np.array([values[n] for n in names])
        cache: dict[bytes, np.ndarray] = {}

        def predicted(x: np.ndarray) -> np.ndarray:
            key = x.tobytes()
            if key not in cache:
                cache[key] = self.predicted(names, values, x)
            return cache[key]

        points = np.repeat(x0[None, :], len(masks), axis=0)
        full = [0] * len(masks)  # whole steps taken
        tries = [0] * len(masks)
        for _ in range(max(steps, default=0) + EXTRA_STEPS):
            for k, keep in enumerate(masks):
                if full[k] >= steps[k] or tries[k] >= steps[k] + EXTRA_STEPS:
                    continue
                tries[k] += 1
                x = points[k]
                r0, jac = self.jacobian(predicted, x, keep, low, high)
                delta, *_ = np.linalg.lstsq(jac, -r0, rcond=None)
                here = half_square(r0)
                for halved in range(STEP_HALVINGS + 1):
                    trial = np.clip(x + delta, low, high)
                    if half_square(self.residuals(predicted(trial), keep)) < here:
                        points[k] = trial
                        full[k] += halved == 0
                        break
                    delta = delta / 2
                else:  # no step lowers the cost: the refit is where it stops
                    tries[k] = steps[k] + EXTRA_STEPS
        return points

    def jacobian(self, predicted: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                 keep: np.ndarray | None, low: np.ndarray, high: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The residuals at ``x`` and their forward-difference Jacobian, (m,) and (m, n).

        ``predicted(x)``: the burst means at the values ``x`` (bounded by ``low`` and
        ``high``; a step that would pass ``high`` goes the other way); only ``keep``'s
        bursts count (None: all).
        """
        h = 1e-6 * np.maximum(np.abs(x), 1e-3 * (high - low))
        h = np.where(x + h > high, -h, h)
        r0 = self.residuals(predicted(x), keep)
        jac = np.column_stack([
            (self.residuals(predicted(x + h[i] * np.eye(x.size)[i]), keep) - r0) / h[i]
            for i in range(x.size)])
        return r0, jac


def half_square(residuals: np.ndarray) -> float:
    """The least-squares cost of ``residuals``: half their sum of squares (unitless)."""
    return 0.5 * float(residuals @ residuals)


def resolution_ftol(cost: float, residuals: int) -> float:
    """least_squares' relative ``ftol`` that stops a fit from ``cost`` at ``COST_RESOLUTION``.

    Its test is a step's decrease below ``ftol`` x the cost after it, at most ``cost``:
    the step then lowered the cost by less than ``COST_RESOLUTION`` units of log-likelihood,
    a unit being 1 of the cost, or ``2 cost / residuals`` for a fit that misfits (the
    log-likelihood with its noise scale fitted, ``-residuals / 2 x log(cost)``).
    """
    if not (cost > 0 and math.isfinite(cost)):
        return FTOL
    return max(FTOL, COST_RESOLUTION / cost, 2.0 * COST_RESOLUTION / max(residuals, 1))


def _bounds(names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([BY_NAME[n].low for n in names]),
            np.array([BY_NAME[n].high for n in names]))


class Fitted(Protocol):
    """What :func:`jackknife` reads of a fitted member (``fit.MemberFit`` has these)."""

    member: Member
    values: dict[str, float]
    held: tuple[str, ...]


def fitted_names(fit: Fitted) -> list[str]:
    """The member's parameters its fit moved: free, not fixed by the member, not held."""
    fixed = dict(fit.member.fixed)
    return [n for n in fit.member.free if n not in fixed and n not in fit.held]


@dataclasses.dataclass(frozen=True)
class FirstOrder:
    """A member's fitted values linearised at their solution, the base of a propagated share.

    :meth:`step` is their first-order answer to changed records or a changed arm (a
    :class:`Problem` on them): one Gauss-Newton step from the solution,
    ``-(J^T J)^-1 J^T dr``, ``dr`` the residuals' change at the solution.
    """

    names: list[str]
    values: dict[str, float]
    x0: np.ndarray
    r0: np.ndarray
    jac: np.ndarray

    @classmethod
    def at(cls, fit: Fitted, problem: Problem) -> FirstOrder:
        """Linearised on ``problem`` (the records and arm the member was fitted on)."""
        names = fitted_names(fit)
        x0 = np.array([fit.values[n] for n in names])
        low, high = _bounds(names)
        r0, jac = problem.jacobian(lambda x: problem.predicted(names, fit.values, x), x0, None,
                                   low, high)
        return cls(names, fit.values, x0, r0, jac)

    def step(self, changed: Problem) -> np.ndarray:
        """The fitted values' first-order move on ``changed``, in their units."""
        change = changed.residuals(changed.predicted(self.names, self.values, self.x0)) - self.r0
        result: np.ndarray = np.linalg.lstsq(self.jac, -change, rcond=None)[0]
        return result


def jackknife(fit: Fitted, train: RecordArrays, arm: dict[str, float], reading: Reading,
              noise_n: float, blocks: int = JACKKNIFE_BLOCKS,
              walk: BiasWalk | None = None) -> dict[str, float]:
    """Resampled 1-sigma of the member's fitted (not held) parameters: the larger of two.

    * Delete-a-block jackknife over trials: the trials with control steps are cut into
      ``blocks`` contiguous blocks, each left out in turn (rows without control steps,
      the surface probe's, stay in every refit: without them stiffness and contact trade
      off); ``sqrt((B-1)/B * sum (theta_b - mean)^2)``. Early exploring trials and later
      worn ones pull the parameters apart where the model misses how the cell changes.
    * Split by force: the contact bursts below and above their median force refitted
      apart (free-space bursts in both); ``|theta_low - theta_high| / 2``, about the full
      fit's sigma when the force law holds over the depths, far more when it does not
      (a linear law on a stiffening foam: its stiffness and contact depend on the depths).
    * Delete-one over the surface probe's points (at least ``MIN_PROBE_POINTS``): the
      probe presses the fresh foam at a few places along the path, and those few presses
      are what part the surface's shape along it (slope, waviness) from the stiffness's,
      which a run holding its force in band cannot; the blocks above keep the probe in
      every refit, so its points' own errors (a sensor zero that moved within one) never
      showed. Hidden cell 28 of seed 1: surface slope 0.0264 +- 0.0008 against 0.030 (4.3
      sigma); left out in turn, the points put it at +- 0.0028.

    Each refit is Gauss-Newton from the member's solution (:meth:`Problem.refits`): one
    step for a block, three for a force half (it was up to 15 iterations of least squares
    per refit, 59 % of a 300-trial fit's time).
    Infinite when there are fewer trials with control steps than blocks.
    """
    names = fitted_names(fit)
    control = np.flatnonzero((train.is_step & train.has_burst).any(axis=1))
    if control.size < blocks or not names:
        return {n: math.inf for n in names}
    problem = Problem(train, arm, reading, noise_n, walk)
    masks = []
    for part in np.array_split(control, blocks):
        rows = np.ones(train.trials, bool)
        rows[part] = False
        masks.append(np.broadcast_to(rows[:, None], problem.use.shape))
    # split by the force the fit predicts, not the force read: most bursts are control steps
    # within a few tenths of a newton of the task's force, where a split on the reading
    # sorts them by their noise, and each half's refit follows its half's noise
    solution = np.array([fit.values[n] for n in names])
    force = np.where(train.has_burst, problem.predicted(names, fit.values, solution), np.nan)
    contact = train.has_burst & (force > max(0.5, 3.0 * (noise_n if math.isfinite(noise_n)
                                                              else 0.0)))
    halves = contact.sum() >= 2 * len(names)
    if halves:
        median = float(np.median(force[contact]))
        masks += [~(contact & (force > median)), ~(contact & (force <= median))]
    halved = len(masks)
    points = np.flatnonzero(train.trial == PROBE_TRIAL)  # a row per probe point (arrays.py)
    probed = points.size >= MIN_PROBE_POINTS
    if probed:
        for row in points:
            rows = np.ones(train.trials, bool)
            rows[row] = False
            masks.append(np.broadcast_to(rows[:, None], problem.use.shape))
    theta = problem.refits(names, fit.values, masks,
                           [BLOCK_STEPS] * blocks + [HALF_STEPS] * (halved - blocks)
                           + [BLOCK_STEPS] * (len(masks) - halved))
    spread = _delete_one(theta[:blocks])
    if halves:
        spread = np.maximum(spread, np.abs(theta[blocks] - theta[blocks + 1]) / 2)
    if probed:
        spread = np.maximum(spread, _delete_one(theta[halved:]))
    return dict(zip(names, spread.tolist(), strict=True))


def _delete_one(theta: np.ndarray) -> np.ndarray:
    """The delete-a-group jackknife's 1-sigma of refits ``theta`` (groups x parameters)."""
    groups = theta.shape[0]
    result: np.ndarray = np.sqrt((groups - 1) / groups
                                 * np.sum((theta - theta.mean(axis=0)) ** 2, axis=0))
    return result
