"""The controller's tick phase under the identification's moves: its share of the sponge's 1-sigma.

The emulated (and a real) controller starts a commanded motion on its interpolation grid
(``tick_s``, 4 ms): at the first tick after the command plus the start delay, so a move is
in position ``T (1/2 - frac(u))`` after the twin's model of it (``u``: the command plus the
delay, in ticks from the grid's zero; :mod:`~forcelearn.tools.twin.arm_model` takes the
mean over ``u``). Where the grid's zero lies on the recorded clock the records do not say
(a real controller's clock is not the PC's), but the commands' own times do say how the
moves' phases go together: the identification's link exchanges take fixed times, so its
step-and-hold and cycle steps are commanded at the same few phases, and their errors do not
average out over the steps. The relaxation is read off those steps' first burst, tens of ms
after in position: hidden cell 13 of seed 2 (a foam relaxing 98 %) put its steps in position
1.6-2.5 ms before the model, and the ratio came out -3.4 sigma (moved 2 ms earlier, -1.6 at
the same cost). The same error as the identified lag's (:func:`~.identify_fit.phase_covariance`).

Each identification move's in-position time is moved by ``T (1/2 - frac(u + theta))`` for
``PHASES`` evenly spaced grid phases ``theta``, and the sponge's first-order response (one
Gauss-Newton step from the member's solution, as :mod:`~.timing_share`) is taken; its root
mean square over ``theta`` is the share, added in quadrature to the 1-sigma. The moves'
own scatter of phase (a real link's jitter in the commands' recorded times) makes the
errors cancel, and the share shrinks with it. The run's own moves are timed within the
link's 44 ms poll windows and are not moved.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from forcelearn.tools.twin.arm import command_s
from forcelearn.tools.twin.arm_model import TICK_S
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.bias import BiasWalk
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.identify import IDENTIFY_TRIAL
from forcelearn.tools.twin.problem import FirstOrder, Fitted, Problem, fitted_names

PHASES = 8
"""Grid phases the share is averaged over (its mean square within 1.3 % of the sawtooth's)."""


def phased_moves(train: RecordArrays) -> np.ndarray:
    """(T, M) bool: the identification's moves, whose in-position time the model took."""
    result: np.ndarray = ((train.trial == IDENTIFY_TRIAL)[:, None] & train.valid
                          & np.isfinite(train.move_mm) & (train.move_mm > 0))
    return result


def phase_lateness_s(train: RecordArrays, arm: dict[str, float], theta: float) -> np.ndarray:
    """How much later than the model each move is in position with the grid at ``theta``, s.

    ``T (1/2 - frac(u + theta))``, ``u`` the command plus the start delay in ticks
    (module doc); (T, M), 0 off the identification's moves.
    """
    tick = float(arm.get("tick_s", TICK_S))
    u = (command_s(train) + arm.get("start_delay_s", 0.0)) / tick
    late = tick * (0.5 - np.mod(np.nan_to_num(u) + theta, 1.0))
    result: np.ndarray = np.where(phased_moves(train), late, 0.0)
    return result


def phase_spread(fit: Fitted, train: RecordArrays, arm: dict[str, float], reading: Reading,
                 noise_n: float, walk: BiasWalk | None = None) -> dict[str, float]:
    """The tick phase's share of each fitted sponge parameter's 1-sigma (module doc).

    Empty when the records hold no identification move or no fitted sponge parameter.
    """
    if not fitted_names(fit) or not phased_moves(train).any():
        return {}
    base = FirstOrder.at(fit, Problem(train, arm, reading, noise_n, walk))
    square = np.zeros(len(base.names))
    for k in range(PHASES):
        late = phase_lateness_s(train, arm, (k + 0.5) / PHASES)
        shifted = Problem(dataclasses.replace(train, in_position_s=train.in_position_s + late),
                          arm, reading, noise_n, walk)
        square += base.step(shifted) ** 2 / PHASES
    return dict(zip(base.names, np.sqrt(square).tolist(), strict=True))
