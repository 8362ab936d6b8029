"""The emulated sensor model: noise, drift, quantisation, saturation, zeroing, resumable state."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams, Jr3SensorModel

FS = np.array(Jr3ModelParams().full_scales)
QUANTUM = FS / 16384
SEEDS = [0, 1, 2, 3, 4]


def _model(seed: int, **params: object) -> Jr3SensorModel:
    return Jr3SensorModel(Jr3ModelParams(**params), np.random.default_rng(seed))


@pytest.mark.parametrize("seed", SEEDS)
def test_noise_std_matches_the_configuration(seed: int) -> None:
    """Per-axis std of 4000 readings of a constant load is the configured noise (+-10 %)."""
    model = _model(seed, bias_drift_per_sqrt_s=(0.0,) * 6)
    truth = np.array([1.0, 19.61, -3.0, 0.2, -0.1, 0.05])
    counts = np.array([model.measure(truth, 0.001) for _ in range(4000)])
    std = (counts * QUANTUM).std(axis=0)
    assert std == pytest.approx(np.array(model.params.noise_std), rel=0.1)


def test_readings_are_whole_counts_of_full_scale_and_saturate_at_int16() -> None:
    """Without noise a load rounds to the nearest count; beyond 2 x full scale it clips."""
    model = _model(0, noise_std=(0.0,) * 6, initial_bias=(0.0,) * 6,
                   bias_drift_per_sqrt_s=(0.0,) * 6)
    truth = np.array([10 * QUANTUM[0] + 0.4 * QUANTUM[0], -3 * FS[1], 0.0, 0.0, 0.0, 2.1 * FS[5]])
    assert model.measure(truth, 0.001) == [10, -32768, 0, 0, 0, 32767]


def test_bias_drifts_as_a_random_walk() -> None:
    """Over 100 s of 50 ms steps the bias spread across seeds is drift * sqrt(100 s) (+-25 %)."""
    finals = []
    for seed in range(40):
        model = _model(seed)
        for _ in range(2000):
            model.measure(np.zeros(6), 0.05)
        finals.append(model.bias - np.array(model.params.initial_bias))
    spread = np.std(finals, axis=0)
    expected = np.array(Jr3ModelParams().bias_drift_per_sqrt_s) * 10.0
    assert spread == pytest.approx(expected, rel=0.25)


@pytest.mark.parametrize("seed", SEEDS)
def test_zeroing_removes_load_and_bias(seed: int) -> None:
    """After zero() the mean reading of the same load is within half the noise per axis."""
    model = _model(seed)
    truth = np.array([3.0, -8.8, 5.0, 0.5, -0.2, 0.1])
    model.zero(truth)
    mean = np.mean([model.measure(truth, 0.001) for _ in range(400)], axis=0) * QUANTUM
    assert np.all(np.abs(mean) < 0.5 * np.array(model.params.noise_std) + QUANTUM)


def test_state_round_trip_resumes_bit_identically() -> None:
    """Saving the state mid-run and loading it into a fresh model replays the same counts."""
    model = _model(7)
    truth = np.array([0.0, 12.0, 0.0, 0.0, 0.0, 0.0])
    for _ in range(50):
        model.measure(truth, 0.001)
    model.zero(truth)
    state = model.state_dict()
    expected = [model.measure(truth, 0.001) for _ in range(100)]
    resumed = _model(999)
    resumed.load_state_dict(state)
    assert [resumed.measure(truth, 0.001) for _ in range(100)] == expected


@pytest.mark.parametrize(
    "params",
    [{"full_scales": (1.0,) * 5}, {"noise_std": (-1.0,) * 6}, {"full_scales": (7000.0,) * 6},
     {"zero_average_samples": 0}],
)
def test_bad_parameters_are_refused(params: dict[str, object]) -> None:
    """Wrong axis counts, negative noise, full scales beyond uint16 are ValueErrors."""
    with pytest.raises(ValueError):
        Jr3ModelParams(**params)
