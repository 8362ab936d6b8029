"""The controller's tick phase under the identification's moves is part of the sponge's 1-sigma.

The controller starts each motion on its 4 ms grid; the twin's model takes the mean over
the command's phase. An identification whose link exchanges take fixed times commands its
steps at one phase, so every step is in position the same 1-2 ms off the model, and the
relaxation read off the bursts right after is biased alike (hidden cell 13 of seed 2: the
relaxation ratio -3.4 sigma, -1.6 with the steps 2 ms earlier).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import forward
from forcelearn.tools.twin.arm import command_s
from forcelearn.tools.twin.arrays import RecordArrays, to_arrays
from forcelearn.tools.twin.identify import IDENTIFY_TRIAL
from forcelearn.tools.twin.params import Member
from forcelearn.tools.twin.phase_share import phase_spread
from forcelearn.tools.twin.problem import Problem
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

READING = forward.Reading.of(DOWN, 1, -1.0)
ARM = base_arm()  # the emulator's defaults
TICK_S = 0.004
TRUTH = SpongeParams(relaxation_ratio=0.9, relaxation_time_s=0.5, softening=0.0, set_mm=0.0)
NAMES = ("surface_y_mm", "stiffness_n_per_mm", "relaxation_ratio", "relaxation_time_s")
NOISE = 0.02
GRID = 0.6
"""Where the controller's grid sits on the recorded clock, ticks (unknown to the twin)."""


@dataclass
class _Fit:
    member: Member
    values: dict[str, float]
    held: tuple[str, ...] = ()


def _identification(phases: np.ndarray | float) -> RecordArrays:
    """A simulated step-and-hold as an identification's, its commands at ``phases`` (ticks)."""
    records = simulate_run(SimulatedRun(trials=8, steps=10, sponge=TRUTH,
                                        sensor=noise_only_sensor(NOISE)), seed=5)
    data = to_arrays(records)
    data = dataclasses.replace(data, trial=np.full_like(data.trial, IDENTIFY_TRIAL))
    u = (command_s(data) + ARM["start_delay_s"]) / TICK_S
    # each command moved back to its phase (less than a tick: the motion is the same)
    return dataclasses.replace(data, start_s=data.start_s - TICK_S * np.mod(u - phases, 1.0))


def _as_modelled(data: RecordArrays) -> RecordArrays:
    """``data`` with the in-position times the twin's model gives: the phase's mean.

    The emulator starts a motion at the first tick after its command plus delay, so it is
    in position ``T (1/2 - frac(u + GRID))`` after the model's time.
    """
    u = (command_s(data) + ARM["start_delay_s"]) / TICK_S
    late = TICK_S * (0.5 - np.mod(u + GRID, 1.0))
    return dataclasses.replace(data, in_position_s=data.in_position_s - late)


def _fitted(data: RecordArrays) -> tuple[_Fit, dict[str, float], dict[str, float]]:
    """The fit on ``data`` (as modelled), its Jacobian 1-sigma and the phase's share."""
    truth = {k: float(v) for k, v in dataclasses.asdict(TRUTH).items()}
    problem = Problem(data, ARM, READING, NOISE)
    x, result = problem.solve(list(NAMES), truth)
    jacobian = dict(zip(NAMES, problem.sigmas(result.jac, result.fun).tolist(), strict=True))
    fit = _Fit(Member("test", NAMES), {**truth, **dict(zip(NAMES, x.tolist(), strict=True))})
    return fit, jacobian, phase_spread(fit, data, ARM, READING, NOISE)


def test_steps_commanded_at_one_phase_widen_the_relaxations_sigma_to_cover_it() -> None:
    """All steps at one phase, 2 ms off the model: the ratio's error is within 3 sigma.

    The Jacobian's 1-sigma alone puts the ratio more than 3 sigma from the truth (5.2); with
    the phase's share added, within 3 (2.3). (At 1.6 ms the other way the error was 3.4
    Jacobian sigmas while the model started every trial relaxed; with the relaxing part the
    last trial's retreat left, 0.8: the steps' phase is then tested where it matters.)
    """
    data = _as_modelled(_identification(0.41))
    fit, jacobian, share = _fitted(data)
    error = abs(fit.values["relaxation_ratio"] - TRUTH.relaxation_ratio)
    assert error > 3 * jacobian["relaxation_ratio"]
    assert error < 3 * np.hypot(jacobian["relaxation_ratio"], share["relaxation_ratio"])


def test_steps_commanded_at_spread_phases_share_little() -> None:
    """Commands at scattered phases: their errors cancel, the share is a fraction of one phase's."""
    rng = np.random.default_rng(1)
    one = _identification(0.3)
    spread = _identification(rng.uniform(size=one.start_s.shape))
    _, _, share_one = _fitted(_as_modelled(one))
    _, _, share_spread = _fitted(_as_modelled(spread))
    assert share_spread["relaxation_ratio"] < 0.5 * share_one["relaxation_ratio"]


def test_no_identification_no_share() -> None:
    """A run's own records (no identification move): no share, the sigmas as before."""
    data = _identification(0.3)
    data = dataclasses.replace(data, trial=np.arange(data.trials))
    fit = _Fit(Member("test", NAMES), {k: float(v) for k, v in dataclasses.asdict(TRUTH).items()})
    assert phase_spread(fit, data, ARM, READING, NOISE) == {}
