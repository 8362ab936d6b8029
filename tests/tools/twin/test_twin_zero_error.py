"""Without a walk (no drift detected) each bias is its zero's value within that zero's error.

A zero taken on one burst of a noisy sensor is off by that burst mean's error: the surface
probe zeroes at each point on one free-space read (0.74 N of noise: +-0.24 N a point), and
pinned at exactly 0 those errors moved hidden cell 11's slope 4.5 sigma and its surface
0.5 mm. An identification tares before its records start: its zero is not in the records at
all, and pinned at 0 its +0.5 N read as a raised surface.
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.records import TrialRecords
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.bias import (
    UNKNOWN_ZERO_VAR_N2,
    Chain,
    build_chain,
    solve_biases,
    tare_zeros,
    walk_terms,
)
from forcelearn.tools.twin.simulate import SimulatedRun, simulate_run


def test_without_a_walk_the_profile_is_the_least_squares_solution() -> None:
    """At q = 0 a linked segment shares its head's bias, a head has its zero's prior.

    The biases equal a brute-force least-squares solve of that problem, and the residual
    terms are its prior rows (before: every bias was its anchor, whatever the bursts read).
    """
    rng = np.random.default_rng(11)
    segment = np.array([[0, 0, 1, 1, -1], [2, 2, 2, 3, 3], [4, -1, 4, 4, 4]])
    linked = np.array([False, True, False, True, False])
    anchor = np.array([0.0, 0.0, 0.2, 0.0, 0.0])
    anchor_var = np.array([0.04, 0.0, 0.01, 0.0, 0.0])  # the last zero exact
    count = linked.size
    chain = Chain(segment, np.arange(count), np.arange(count, dtype=float),
                  np.ones(count), linked, anchor, anchor_var, np.zeros(count, int), 0)
    residual = rng.normal(0.3, 0.4, segment.shape)
    weights = np.where(segment >= 0, rng.uniform(1.0, 10.0, segment.shape), 0.0)
    biases = solve_biases(chain, residual, weights, 0.0)

    heads = [0, 2, 4]
    head_of = np.array([0, 0, 1, 1, 2])
    free = [0, 1]  # the exact zero's head is fixed at its anchor
    rows, targets = [], []
    for t, m in zip(*np.nonzero(segment >= 0), strict=True):
        h = head_of[segment[t, m]]
        row = np.zeros(len(free))
        if h in free:
            row[free.index(h)] = weights[t, m]
        rows.append(row)
        targets.append(weights[t, m] * (residual[t, m] - (anchor[heads[h]] if h not in free
                                                          else 0.0)))
    for h in free:
        row = np.zeros(len(free))
        scale = 1.0 / math.sqrt(anchor_var[heads[h]])
        row[free.index(h)] = scale
        rows.append(row)
        targets.append(scale * anchor[heads[h]])
    design, target = np.array(rows), np.array(targets)
    brute, *_ = np.linalg.lstsq(design, target, rcond=None)
    expected = np.array([brute[0], brute[0], brute[1], brute[1], anchor[4]])
    assert np.allclose(biases, expected, rtol=1e-10, atol=1e-12)
    terms = walk_terms(chain, biases, 0.0)
    prior = (design @ brute - target)[-len(free):]
    assert np.allclose(terms[heads[:2]], prior, atol=1e-10)
    assert np.all(terms[[1, 3, 4]] == 0.0)


def test_a_zero_taken_on_a_noisy_burst_lets_its_bias_follow_the_reads() -> None:
    """Trials zeroed on a noisy burst, read +0.3 N off it: the bias follows the reads.

    With the zero's error (its variance from the noise and the burst's samples) the bias
    moves most of the way to what the trial's free-space reads say.
    """
    run = SimulatedRun(trials=3, zero_check_each_trial=True, burst_samples=8)
    records = simulate_run(run, seed=2)
    data = to_arrays(records)
    chain = build_chain(data, tare_zeros(records, 0.5, 0.0))
    assert not chain.linked.any() and np.all(chain.anchor_var_n2[1:] > 0)
    residual = np.where(data.has_burst, 0.3, np.nan)
    weights = np.where(data.has_burst, 1 / 0.05, 0.0)
    biases = solve_biases(chain, residual, weights, 0.0)
    assert biases[0] == 0.0  # the run's own tare at its start: exact
    assert np.all(biases[1:] > 0.2) and np.all(biases[1:] < 0.3)


def test_an_unanchored_trial_reads_its_zero_from_its_bursts() -> None:
    """A trial whose zero is not in the records (an identification's) has its bias read.

    Before, it started from the run's tare at 0, exactly, whatever its free reads said.
    """
    run = SimulatedRun(trials=2)
    records = simulate_run(run, seed=4)
    extra = TrialRecords(-2, records[0].steps, [])
    data = to_arrays([extra, records[1]])
    chain = build_chain(data, tare_zeros([records[1]]), unanchored=frozenset({-2}))
    first = chain.segment[0][data.has_burst[0]]
    assert chain.anchor_var_n2[first[0]] == UNKNOWN_ZERO_VAR_N2
    residual = np.where(data.has_burst, 0.5, np.nan)
    residual[1] = 0.0
    weights = np.where(data.has_burst, 10.0, 0.0)
    biases = solve_biases(chain, residual, weights, 0.0)
    assert np.allclose(biases[np.unique(first)], 0.5)
    assert np.allclose(biases[np.unique(chain.segment[1][data.has_burst[1]])], 0.0)

