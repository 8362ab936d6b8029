"""An identification's zero walks even where the run's tares cannot tell its drift from 0.

The tares of a 60-trial run (a zero check at each trial's end, ~16 s apart, on noisy single
bursts) put half the hidden cells' drift at "not told from 0", and the walk was switched off
for the whole fit: the identification's one bias then held still over its minutes at one
place, and the zero's walk between its free-space reads and its presses went into the
surface. Its bias now walks at the largest rate the tares allow; the run's own trials keep
theirs at their zeros (a walk the records do not show would soak up the wear).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.records import TrialRecords
from forcelearn.tools.experiments.records import PROBE_TRIAL
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.bias import BiasWalk, DriftEstimate, build_chain, tare_zeros
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.problem import Problem, burst_weights
from forcelearn.tools.twin.sensor import fit_sensor
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

READING = Reading.of(DOWN, 1, -1.0)
NOISE = 0.02
RATE = 0.02
"""The zero's walk, N/sqrt(s): the emulated sensor's default drift."""
IDENT = -2
CELL = SpongeParams(relaxation_ratio=0.6, relaxation_time_s=0.5, softening=0.0, set_mm=0.0,
                    waviness_mm=0.0, stiffness_variation=0.0, surface_slope=0.0)
TRUTH = {k: float(v) for k, v in dataclasses.asdict(CELL).items()}


def _biases(allowed: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An identification whose zero walks, then two trials: the profiled and the true biases.

    The tares do not tell the drift from 0 (``DriftEstimate(0, inf)``) and allow ``allowed``.
    Returns the profiled biases at the truth (T, M), the walk added to the identification's
    first row (T, M), that row, and each row's trial.
    """
    run = SimulatedRun(trials=2, probe_points=(0.2, 0.5, 0.8), probe_dwell_s=1.0,
                       sponge=CELL, sensor=noise_only_sensor(NOISE))
    records = simulate_run(run, seed=3)
    ident = [TrialRecords(IDENT, r.steps, []) for r in records if r.trial < 0]
    trials = [r for r in records if r.trial > 0]
    data = to_arrays(ident + trials)
    rows = np.arange(data.trials) == np.flatnonzero(data.trial == IDENT)[0]  # its first row
    moment = np.where(data.has_burst & rows[:, None], data.burst_start_s, np.inf).ravel()
    order = np.argsort(moment)[: int((data.has_burst & rows[:, None]).sum())]
    steps = np.diff(np.concatenate([[0.0], moment[order]]))
    walk = np.zeros(moment.size)
    walk[order] = np.cumsum(np.random.default_rng(0).normal(0.0, RATE * np.sqrt(steps)))
    walk = walk.reshape(data.mean_n.shape)
    data = dataclasses.replace(data, mean_n=data.mean_n + walk)
    unanchored = frozenset({IDENT})
    weights = burst_weights(data, NOISE)
    labels = np.broadcast_to(data.trial[:, None], data.has_burst.shape)
    profile = BiasWalk(build_chain(data, tare_zeros([]), unanchored=unanchored,
                                   per_burst=unanchored), data, tare_zeros([]), weights,
                       weights, DriftEstimate(0.0, math.inf, "tares", 10, allowed),
                       labels, data.mean_n, unanchored)
    names = list(TRUTH)
    predicted = Problem(data, base_arm(), READING, NOISE, profile).predicted(
        names, TRUTH, np.array([TRUTH[n] for n in names]))
    debiased, _ = profile.debiased(predicted, predicted)
    return np.where(data.has_burst, debiased - predicted, np.nan), walk, rows, data.trial


def test_the_identifications_bias_follows_its_walk_where_the_drift_is_not_detected() -> None:
    """Walking at the rate the tares allow, its biases follow the zero; held still, they do not.

    The trials' biases stay at their zero either way.
    """
    followed, walk, rows, trials = _biases(RATE)
    held, _, _, _ = _biases(math.nan)
    ident = ~np.isnan(followed) & rows[:, None]
    true = walk[ident] - np.mean(walk[ident])
    error_followed = followed[ident] - np.mean(followed[ident]) - true
    error_held = held[ident] - np.mean(held[ident]) - true
    assert np.ptp(walk[ident]) > 5 * NOISE / 4  # the walk is seen over the noise
    assert np.ptp(held[ident]) < 1e-12  # one bias held still
    assert np.sqrt(np.mean(error_followed**2)) < 0.3 * np.sqrt(np.mean(error_held**2))
    trial = ~np.isnan(followed) & (trials > 0)[:, None]
    assert trial.any() and np.all(followed[trial] == 0.0)


def test_the_tares_allow_a_walk_where_they_put_its_rate_at_0() -> None:
    """The tares' largest rate at 1 sigma is finite and above their estimate, also at 0."""
    run = SimulatedRun(trials=12, tare_each_trial=True, sponge=CELL,
                       sensor=noise_only_sensor(0.3))
    records = simulate_run(run, seed=2)
    sensor = fit_sensor(records, to_arrays(records), None, None)
    assert sensor.tares >= 3
    assert math.isfinite(sensor.drift_allowed)
    assert sensor.drift_allowed > 0 and sensor.drift_allowed >= sensor.drift_n_per_sqrt_s


def test_the_probes_bias_follows_its_walk_burst_by_burst_where_the_walk_is_on() -> None:
    """With a detected drift each probe burst is a segment of its own; without, as before.

    (And so is every trial's: ``test_twin_walked.py``.)
    """
    run = SimulatedRun(trials=2, probe_points=(0.2, 0.5), probe_dwell_s=1.0, sponge=CELL,
                       sensor=noise_only_sensor(NOISE))
    records = simulate_run(run, seed=3)
    data = to_arrays(records)
    probe = data.trial == PROBE_TRIAL
    weights = burst_weights(data, NOISE)
    labels = np.broadcast_to(data.trial[:, None], data.has_burst.shape)

    def walk(drift: DriftEstimate) -> BiasWalk:
        return BiasWalk(build_chain(data, tare_zeros(records)), data, tare_zeros(records),
                        weights, weights, drift, labels, data.mean_n)

    on = walk(DriftEstimate(RATE, 0.1 * RATE, "tares", 10))
    fine = on.at_bursts(data)
    bursts = int(data.has_burst[probe].sum())
    assert on.train.size < bursts
    assert int(np.sum(fine.train.trial_of == PROBE_TRIAL)) == bursts
    assert fine.train.size == int(data.has_burst.sum())
    off = walk(DriftEstimate(0.0, math.inf, "tares", 10))
    assert off.at_bursts(data) is off
