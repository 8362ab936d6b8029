"""The sensor's bias as a profiled random walk (twin/bias.py): the solve, the drift, the fit."""

from __future__ import annotations

import dataclasses
import gzip
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TareRecord, TrialRecords
from forcelearn.tools.twin import bias, forward
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.bias import Chain, build_chain, solve_biases, tare_zeros, walk_terms
from forcelearn.tools.twin.fit import TwinFit, fit_twin
from forcelearn.tools.twin.replay import replay
from forcelearn.tools.twin.sensor import fit_sensor, mean_share, tare_reads
from forcelearn.tools.twin.setup import base_arm, base_sponge, configured_colour, reading_of
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run
from forcelearn.tools.twin.source import read_runs

READING = forward.Reading.of(DOWN, 1, -1.0)
BASE_ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
            "lag_s": 0.03}
SPONGE = SpongeParams(
    surface_y_mm=0.6, surface_slope=0.02, waviness_mm=0.7, stiffness_n_per_mm=3.2,
    stiffness_variation=0.1, softening=0.3, softening_passes=25.0, set_mm=1.5, set_passes=20.0,
    relaxation_ratio=0.4, relaxation_time_s=0.3,
)
DRIFT = 0.03
"""N/sqrt(s): 1.5 x the emulated JR3's; over the 25 trials (~260 s) the bias wanders ~0.5 N."""
NOISE = 0.02
RUN = SimulatedRun(trials=25, sponge=SPONGE, sensor=Jr3ModelParams(
    noise_std=(NOISE,) * 6, initial_bias=(0.0,) * 6, bias_drift_per_sqrt_s=(DRIFT,) * 6))
COLOUR = math.exp(-2 * math.pi * RUN.cutoff_hz * RUN.sample_period_s)


def _base() -> dict[str, float]:
    return {k: float(v) for k, v in dataclasses.asdict(SpongeParams()).items()}


@pytest.fixture(scope="module")
def drifting() -> TwinFit:
    """The fit of a noiseless-sponge cell whose sensor drifts and is tared only at the start."""
    return fit_twin(simulate_run(RUN, seed=0), _base(), BASE_ARM, READING, 0.1, 0.004,
                    configured_phi=COLOUR)


def test_the_profile_solve_is_the_least_squares_solution() -> None:
    """The tridiagonal solve equals a brute-force least-squares solve of the same problem."""
    rng = np.random.default_rng(7)
    trials, moves, count = 4, 6, 6
    segment = np.array([[0, 0, 1, 1, 1, -1], [2, 2, 2, 2, -1, -1], [3, 3, 4, 4, 4, 4],
                        [5, -1, 5, 5, 5, 5]])
    assert segment.shape == (trials, moves)
    linked = np.array([False, True, True, False, True, False])  # tares before 0, 3 and 5
    anchor = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.3])  # 5 starts from a known bias
    anchor_var = np.where(linked, 0.0, rng.uniform(0.0, 0.01, count))  # the zeros' errors
    chain = Chain(segment, np.arange(count), np.cumsum(rng.uniform(5, 20, count)),
                  rng.uniform(1, 30, count), linked, anchor, anchor_var,
                  np.zeros(count, int), 0)
    residual = rng.normal(0.2, 0.5, (trials, moves))
    weights = np.where(segment >= 0, rng.uniform(0.5, 20, (trials, moves)), 0.0)
    weights[2, 3] = 0.0  # a burst that must not inform the bias
    rate = 0.05
    biases = solve_biases(chain, residual, weights, rate)

    rows, targets = [], []
    for t, m in zip(*np.nonzero(segment >= 0), strict=True):
        row = np.zeros(count)
        row[segment[t, m]] = weights[t, m]
        rows.append(row)
        targets.append(weights[t, m] * residual[t, m])
    for s in range(count):
        row = np.zeros(count)
        scale = 1.0 / math.sqrt(rate**2 * chain.gap_s[s] + anchor_var[s])
        row[s] = scale
        if linked[s]:
            row[s - 1] = -scale
            targets.append(0.0)
        else:
            targets.append(scale * anchor[s])
        rows.append(row)
    design, target = np.array(rows), np.array(targets)
    brute, *_ = np.linalg.lstsq(design, target, rcond=None)
    assert np.allclose(biases, brute, rtol=1e-10, atol=1e-12)
    # the walk's residual terms are the penalty rows of that problem
    penalty = (design @ biases - target)[-count:]
    assert np.allclose(walk_terms(chain, biases, rate), penalty, atol=1e-10)


def test_no_drift_keeps_the_biases_at_the_tares_zero() -> None:
    """At q = 0 the biases are their anchors: the fit is today's (no bias)."""
    records = simulate_run(dataclasses.replace(RUN, trials=3), seed=1)
    data = to_arrays(records)
    chain = build_chain(data, tare_zeros([]))
    biases = solve_biases(chain, data.mean_n, np.ones(data.mean_n.shape), 0.0)
    assert chain.size == 3 and not chain.linked[0] and chain.linked[1:].all()
    assert np.all(biases == 0.0)


def test_tares_restart_the_walk() -> None:
    """A trial preceded by a tare starts a new walk from 0 at the tare's time."""
    records = simulate_run(dataclasses.replace(RUN, trials=3, tare_each_trial=True), seed=1)
    data = to_arrays(records)
    tares = {t.trial: t.tares[-1].time_s for t in records}
    chain = build_chain(data, tare_zeros(records))
    assert not chain.linked.any()
    first_burst = np.nanmin(np.where(data.has_burst, data.burst_start_s, np.nan), axis=1)
    assert np.all(chain.time_s - chain.gap_s >= np.array(list(tares.values())) - 1e-9)
    assert np.all(chain.time_s - chain.gap_s <= first_burst)


def test_a_zero_check_at_a_trials_end_restarts_the_next_trials_walk() -> None:
    """The §5 run's zero check closes each trial: the NEXT trial's walk starts there.

    The check's own burst is read against the trial's zero; the walk after it starts from
    the check's burst mean's error, not from an exact 0. (Taken as the trial's own tare,
    the check pinned every trial's bias to 0 over a 1 ms gap: no walk at all.)
    """
    run = dataclasses.replace(RUN, trials=4, zero_check_each_trial=True)
    records = simulate_run(run, seed=1)
    data = to_arrays(records)
    noise = 0.2
    chain = build_chain(data, tare_zeros(records, noise, COLOUR))
    ends = [t.tares[-1].time_s for t in records]
    assert chain.size == 4 and not chain.linked[0]
    assert chain.time_s[0] - chain.gap_s[0] == pytest.approx(data.start_s[0, 0])
    assert not chain.linked[1:].any()
    assert np.allclose(chain.time_s[1:] - chain.gap_s[1:], ends[:-1])  # from the last check
    assert np.all(chain.gap_s[1:] > 1.0)
    last_bursts = np.array([data.burst_start_s[row][data.has_burst[row]][-1]
                            for row in range(4)])
    assert np.allclose(last_bursts, ends)  # each check's burst read against the old zero
    assert (chain.segment[data.has_burst] == np.repeat(np.arange(4),
                                                        data.has_burst.sum(axis=1))).all()
    expected = noise**2 * mean_share(COLOUR, run.burst_samples)
    assert np.allclose(chain.anchor_var_n2[1:], expected)


def test_the_drift_rate_is_recovered_within_its_uncertainty(drifting: TwinFit) -> None:
    """No tare after the start: the free-space reads of successive trials measure the drift."""
    sensor = drifting.sensor
    assert sensor.tares == 0
    assert sensor.drift_source == "free-space reads"
    assert sensor.drift_sigma < 0.35 * DRIFT
    assert abs(sensor.drift_n_per_sqrt_s - DRIFT) <= 2.5 * sensor.drift_sigma


def test_the_drift_does_not_leak_into_contact_stiffness_or_wear(drifting: TwinFit) -> None:
    """A drifting zero is not the sponge: the contact, stiffness and wear stay the truth's.

    Without the bias's walk (main before this module) the same records gave a stiffness
    1.6 % high, the surface 0.08 mm low, softening 0.18 and set 30 mm (truth 0.3, 1.5).
    """
    values, truth = drifting.chosen.values, dataclasses.asdict(SPONGE)
    assert values["stiffness_n_per_mm"] == pytest.approx(truth["stiffness_n_per_mm"], rel=0.01)
    assert values["surface_y_mm"] == pytest.approx(truth["surface_y_mm"], abs=0.05)
    assert values["softening"] == pytest.approx(truth["softening"], rel=0.15)
    assert values["set_mm"] == pytest.approx(truth["set_mm"], rel=0.12)


NETFT = Path(__file__).parent / "data" / "netft-30"
"""The records of ``forcelearn run --config examples/netft-cell.toml --trials 30 --seed 0``
(probe + 30 trials, gzipped) and the run's config: the default sponge, so in the family."""


@pytest.mark.slow
@pytest.mark.long
def test_the_netft_default_cell_is_represented(tmp_path: Path) -> None:
    """The default cell read by a Net F/T is represented: its sponge is in the family.

    The Net F/T's noise is low (0.05 N), so its bias's wander over the run (tenths of a
    newton) shows: without the bias's walk (main before it) the held-out trials missed
    the bar (0.154 N against 0.101 N) and the cell was declared not represented.
    """
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    shutil.copy(NETFT / "config.toml", run_dir / "config.toml")
    with gzip.open(NETFT / "records.mcap.gz") as packed:
        (run_dir / "records.mcap").write_bytes(packed.read())
    source = read_runs([run_dir])
    config = source.config
    arm = ArmConfig()
    fit = fit_twin(source.records, base_sponge(config), base_arm(), reading_of(config),
                   arm.in_position_mm, arm.tick_s,
                   configured_phi=configured_colour(config, source.records))
    assert fit.represented, fit.reason
    assert fit.sensor.drift_source == "free-space reads"


def test_replay_reads_the_sensor_zero_from_free_space(tmp_path: Path) -> None:
    """The run's own cell replayed by the forward model: only the bias's wander is left.

    The true sponge predicts the recorded force but not the Net F/T's drifting zero; read
    from the free-space bursts (as a tare would) it goes, and the RMS falls to the bursts'
    noise (0.05 N per sample).
    """
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    shutil.copy(NETFT / "config.toml", run_dir / "config.toml")
    with gzip.open(NETFT / "records.mcap.gz") as packed:
        (run_dir / "records.mcap").write_bytes(packed.read())
    source = read_runs([run_dir])
    result = replay(source.records, source.config, "forward")
    assert result.raw_overall_rms_n > 0.07  # the drift: tenths of a newton over the run
    assert result.overall_rms_n < 0.5 * result.raw_overall_rms_n
    assert result.overall_rms_n < 0.05


@pytest.mark.parametrize("rate", [0.0, 0.02, 0.05])
def test_the_walk_rate_is_measured_through_noisy_single_reads(rate: float) -> None:
    """One 0.2 N read per 16 s trial, 250 trials: q within 3 sigma, told from 0 only if > 0.

    (The moment estimate on successive increments left a default run's 0.019 N/sqrt(s)
    undetected: one read's noise is larger than one trial's walk.)
    """
    rng = np.random.default_rng(int(rate * 1000) + 1)
    count, gap, noise = 250, 16.0, 0.2
    times = gap * np.arange(1, count + 1)
    walk = np.cumsum(rate * np.sqrt(gap) * rng.standard_normal(count))
    reads = bias.ReadSeries(
        value=walk + noise * rng.standard_normal(count), variance=np.full(count, noise**2),
        time_s=times, restart_s=np.concatenate([[0.0], np.full(count - 1, np.nan)]),
        anchor_n=np.zeros(count), anchor_var_n2=np.zeros(count))
    estimate, sigma = bias.walk_rate(reads)
    assert abs(estimate - rate) < 3 * sigma + 1e-3
    assert bias.drift_detected(estimate, sigma) == (rate > 0)


def _checked_run(rate: float, noise: float, phi: float, trials: int, seed: int,
                 gap_s: float = 16.0, samples: int = 25) -> list[TrialRecords]:
    """Trials that each end with a zero check in free space (the §5 run's records).

    The check's burst is on the trial's last move; a software zero on its mean follows.
    """
    rng = np.random.default_rng(seed)
    walk, zero, out = 0.0, 0.0, []
    for trial in range(trials):
        time_s = (trial + 1) * gap_s
        walk += rate * math.sqrt(gap_s) * rng.standard_normal()
        shocks = rng.standard_normal(samples)
        ar = np.empty(samples)
        ar[0] = noise * shocks[0]
        for k in range(1, samples):
            ar[k] = phi * ar[k - 1] + noise * math.sqrt(1 - phi**2) * shocks[k]
        mean = walk + float(ar.mean()) - zero
        zero += mean
        move = MoveRecord((0.0, 15.0, 0.0), (0.0, 15.0, 0.0), time_s - 0.5, time_s - 0.1,
                          time_s)
        burst = BurstRecord(mean, noise, mean, mean, samples, time_s, 0.024, mean + 0.01)
        out.append(TrialRecords(trial, [StepRecord(trial, 0, "retreat", move, burst)],
                                [TareRecord(trial, time_s, (0.0, 15.0, 0.0), mean + 0.01,
                                            True)]))
    return out


def test_zero_checks_measure_the_drift_within_its_sigma() -> None:
    """Each check reads the walk since the last one plus BOTH bursts' errors.

    The default cell's figures (0.02 N/sqrt(s), 0.2 N noise coloured by the 125 Hz low-pass
    at 1 ms, 25-sample checks 16 s apart, 300 trials): counting one burst's error put the
    drift at 0.025-0.029 +- 0.0011 on every seed of the default run (5-6 sigma high).
    """
    rate, noise, phi = 0.02, 0.2, math.exp(-2 * math.pi * 125.0 * 0.001)
    scores = []
    for seed in range(12):
        records = _checked_run(rate, noise, phi, 300, seed)
        fitted = fit_sensor(records, to_arrays(records), None, None, phi)
        assert fitted.tares == 300
        scores.append((fitted.drift_n_per_sqrt_s - rate) / fitted.drift_sigma)
    scores_arr = np.array(scores)
    assert np.all(np.abs(scores_arr) < 3.0), scores_arr
    assert abs(scores_arr.mean()) < 3.0 / math.sqrt(len(scores))  # no bias
    assert 0.5 < float(np.sqrt(np.mean(scores_arr**2))) < 1.6  # the sigma is the scatter's


def test_reads_recorded_after_a_zero_check_at_its_time_are_read_against_it() -> None:
    """A probe point's zero check, then its free-space reads: one settled time, three bursts.

    The cell's clock does not run during a read, so the check's burst and the reads after
    the zero carry the same time: the tare's burst is the one whose filtered force it
    recorded, and only the bursts recorded after it start the new walk (taking every burst
    at the tare's time as read before it put the two free reads on the old zero).
    """
    def burst(mean: float, count: int, filtered: float, start_s: float = 30.0) -> BurstRecord:
        return BurstRecord(mean, 0.2, mean, mean, count, start_s, 0.02, filtered)

    here = (900.0, 15.0, 0.0)
    before = MoveRecord(here, here, 10.0, 10.4, 10.5)
    moved = MoveRecord(here, here, 29.5, 29.9, 30.0)
    held = MoveRecord(here, (math.nan,) * 3, 30.0, 30.0, 30.0)
    steps = [StepRecord(-1, 0, "probe", before, burst(0.05, 16, 0.05, 10.5)),
             StepRecord(-1, 1, "probe", moved, burst(0.41, 25, 0.40)),  # the zero check
             StepRecord(-1, 1, "probe", held, burst(-0.02, 16, -0.02)),
             StepRecord(-1, 1, "probe", held, burst(0.03, 16, 0.03))]
    records = [TrialRecords(-1, steps, [TareRecord(-1, 30.0, here, 0.40, True)])]
    data = to_arrays(records)
    reads = tare_reads(records)
    assert [(r.mean_n, r.count, r.rank) for r in reads] == [(0.41, 25, 0)]
    chain = build_chain(data, tare_zeros(records, 0.2, COLOUR))
    # a row per probe point (arrays.by_probe_point): point 0's read; point 1's check and reads
    assert chain.segment[data.has_burst].tolist() == [0, 1, 2, 2]
    assert chain.linked.tolist() == [False, True, False]
    assert chain.time_s[2] - chain.gap_s[2] == 30.0
    assert chain.anchor_var_n2[2] == pytest.approx(0.04 * mean_share(COLOUR, 25))
