"""An identification's sensor bias is followed from burst to burst (``fit.walked_fits``).

Its holds last minutes at one place while the sensor's zero walks; a bias held over 20 s
slices leaves that walk in the holds' curves and the relaxation fitted to them bends to it
(hidden cells 11 and 26 of seed 3: ratio -4.2 and -4.5 sigma). Per burst, the biases
profiled out take up part of each residual, which the sandwich's degrees of freedom count.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.records import TrialRecords
from forcelearn.tools.experiments.records import PROBE_TRIAL
from forcelearn.tools.twin import fit as fit_module
from forcelearn.tools.twin.arrays import RecordArrays, to_arrays
from forcelearn.tools.twin.bias import BiasWalk, DriftEstimate, build_chain, tare_zeros
from forcelearn.tools.twin.fit import MemberFit, walked_fits
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import Member
from forcelearn.tools.twin.problem import Problem, burst_weights
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

ARM = base_arm()
READING = Reading.of(DOWN, 1, -1.0)
NOISE = 0.02
RATE = 0.02
"""The walk's rate, N/sqrt(s): the emulated sensor's default drift."""
IDENT = -2
MEMBER = Member("linear", ("surface_y_mm", "stiffness_n_per_mm", "relaxation_ratio",
                           "relaxation_time_s"))
CELL = SpongeParams(relaxation_ratio=0.6, relaxation_time_s=0.5, softening=0.0, set_mm=0.0,
                    waviness_mm=0.0, stiffness_variation=0.0, surface_slope=0.0)
TRUTH = {k: float(v) for k, v in dataclasses.asdict(CELL).items()}


def _identification(seed: int, walk_seed: int) -> tuple[RecordArrays, BiasWalk]:
    """Presses held at five places, read as an identification, the sensor's zero walking.

    The identification's zero is not in its records; the zero walks at ``RATE``. Returned
    with the walk the fit profiles first, in 20 s slices.
    """
    run = SimulatedRun(trials=0, probe_points=(0.1, 0.3, 0.5, 0.7, 0.9), probe_dwell_s=1.0,
                       sponge=CELL, sensor=noise_only_sensor(NOISE))
    records = simulate_run(run, seed=seed)
    data = to_arrays([TrialRecords(IDENT, r.steps, []) for r in records if r.steps])
    moment = np.where(data.has_burst, data.burst_start_s, np.inf).ravel()
    order = np.argsort(moment)[: int(data.has_burst.sum())]
    steps = np.diff(np.concatenate([[0.0], moment[order]]))
    rng = np.random.default_rng(walk_seed)
    bias = np.zeros(moment.size)
    bias[order] = np.cumsum(rng.normal(0.0, RATE * np.sqrt(steps)))
    data = dataclasses.replace(data, mean_n=data.mean_n + bias.reshape(data.mean_n.shape))
    unanchored = frozenset({IDENT})
    weights = burst_weights(data, NOISE)
    labels = np.broadcast_to(data.trial[:, None], data.has_burst.shape)
    sliced = BiasWalk(build_chain(data, tare_zeros([]), unanchored=unanchored), data,
                      tare_zeros([]), weights, weights,
                      DriftEstimate(RATE, 0.1 * RATE, "tares", 10), labels, data.mean_n,
                      unanchored)
    return data, sliced


def test_the_members_are_refitted_from_their_own_solutions_with_a_bias_per_burst(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Each identification burst its own bias segment, every member refitted from its fit.

    What the fit held stays held (:func:`fit_member`'s ``kept``).
    """
    data, sliced = _identification(3, 0)
    fits = [MemberFit(MEMBER, dict(TRUTH), {}, 0.0, 0.0, 0.0, 4, train_cost=1.0,
                      eligible=False, note="dropped")]
    refits: list[dict[str, Any]] = []

    def refit(member: Member, train: RecordArrays, heldout: RecordArrays,
              start: dict[str, float], *args: Any, **kwargs: Any) -> MemberFit:
        refits.append({"member": member, "start": start, "walk": args[-2], **kwargs})
        return dataclasses.replace(fits[0], train_cost=-1.0, eligible=True, note="")

    monkeypatch.setattr(fit_module, "fit_member", refit)
    walk, result = walked_fits(fits, data, data, TRUTH, ARM, READING, NOISE, sliced)
    assert sliced.train.size < 5 and walk.train.size == int(data.has_burst.sum())
    assert [r["member"] for r in refits] == [MEMBER] and refits[0]["start"] == TRUTH
    assert refits[0]["walk"] is walk and refits[0]["kept"] is fits[0]  # its holds kept
    assert result[0].train_cost == -1.0
    assert (result[0].eligible, result[0].note) == (False, "dropped")  # the verdict kept
    still = dataclasses.replace(sliced, unanchored=frozenset(),
                                drift=DriftEstimate(0.0, RATE, "tares", 10))
    refits.clear()
    assert walked_fits(fits, data, data, TRUTH, ARM, READING, NOISE, still) == (still, fits)
    assert refits == []  # no walk: nothing to follow burst to burst


def test_where_the_zero_walks_every_trials_bursts_follow_it() -> None:
    """The walk on, a run's own trials (tared, anchored) get a bias per burst too.

    Their zero walks from the trial's tare to each burst as it does in a hold (0.07 N over a
    12 s trial at 0.02 N/sqrt(s)); held over the trial, that walk leaned hidden cell 02 of
    seed 6's softening to -3.7 sigma (per burst: -2.4).
    """
    data, sliced = _identification(3, 0)
    anchored = dataclasses.replace(sliced, unanchored=frozenset())
    assert anchored.rate > 0 and anchored.train.size < 5
    fine = anchored.at_bursts(data)
    assert fine.train.size == int(data.has_burst.sum())
    off = dataclasses.replace(anchored, drift=DriftEstimate(0.0, RATE, "tares", 10))
    assert off.at_bursts(data) is off


def test_with_a_bias_per_burst_the_ratios_sigma_is_its_scatter() -> None:
    """Over 16 draws of the walk and the noise the ratio's z has a mean square near 1.

    Counted with the fitted parameters only, the sandwich's degrees of freedom ignored the
    biases profiled out (one per burst, each with its walk term): z^2 averaged 2.2.
    """
    names = list(MEMBER.free)
    ratio = names.index("relaxation_ratio")
    squares = []
    for draw in range(16):
        data, sliced = _identification(draw % 5, 1000 + draw)
        problem = Problem(data, ARM, READING, NOISE, sliced.at_bursts(data))
        x, result = problem.solve(names, TRUTH)
        sigma = problem.sigmas(result.jac, result.fun)
        squares.append(((x[ratio] - TRUTH["relaxation_ratio"]) / sigma[ratio]) ** 2)
    assert 0.5 < np.mean(squares) < 1.5


def test_a_continued_fit_keeps_what_it_held() -> None:
    """``fit_member(kept=...)``: the values the fit it continues held stay at theirs."""
    data, sliced = _identification(3, 0)
    values = {**TRUTH, "relaxation_time_s": 0.4}  # held away from the cell's 0.5
    kept = MemberFit(MEMBER, values, {n: 0.01 for n in MEMBER.free}, 0.0, 0.0, 0.0, 3,
                     held=("relaxation_time_s",))
    fit = fit_module.fit_member(MEMBER, data, data, values, TRUTH, ARM, READING, NOISE,
                                sliced.at_bursts(data), kept=kept)
    assert fit.held == ("relaxation_time_s",) and fit.values["relaxation_time_s"] == 0.4
    assert fit.sigmas["relaxation_time_s"] == 0.01 and fit.free == 3


def test_the_probes_bias_is_followed_per_burst_beside_an_identification() -> None:
    """The surface probe's points hold a minute at one place too: its bursts get a bias each.

    Sliced, its zero walking within 20 s pulled the slope, the contact and the relaxation
    (hidden cell 13 of seed 2). Without an identification too, where the walk is on; a walk
    that is off stays as it is.
    """
    run = SimulatedRun(trials=0, probe_points=(0.1, 0.5, 0.9), probe_dwell_s=1.0,
                       sponge=CELL, sensor=noise_only_sensor(NOISE))
    probe = [r for r in simulate_run(run, seed=3) if r.steps]
    assert {r.trial for r in probe} == {PROBE_TRIAL}
    data = to_arrays([*probe, *(TrialRecords(IDENT, r.steps, []) for r in probe)])
    weights = burst_weights(data, NOISE)
    labels = np.broadcast_to(data.trial[:, None], data.has_burst.shape)

    def walk(unanchored: frozenset[int], rate: float = RATE) -> BiasWalk:
        return BiasWalk(build_chain(data, tare_zeros([]), unanchored=unanchored), data,
                        tare_zeros([]), weights, weights,
                        DriftEstimate(rate, 0.1 * rate, "tares", 10), labels, data.mean_n,
                        unanchored)

    fine = walk(frozenset({IDENT})).at_bursts(data)
    for trial in (PROBE_TRIAL, IDENT):
        bursts = data.has_burst & (data.trial == trial)[:, None]
        assert np.unique(fine.train.segment[bursts]).size == int(bursts.sum())
    probe_bursts = data.has_burst & (data.trial == PROBE_TRIAL)[:, None]
    anchored = walk(frozenset()).at_bursts(data)
    assert np.unique(anchored.train.segment[probe_bursts]).size == int(probe_bursts.sum())
    still = walk(frozenset(), rate=0.0)
    assert still.at_bursts(data) is still
