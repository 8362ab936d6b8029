"""The Kalman force filter: accuracy on an emulated step-and-ramp profile, gaps, outliers, R."""

from __future__ import annotations

import itertools
import os
import threading

import can
import numpy as np
import pytest

from forcelearn.devices import Pose, WrenchSample
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge, surface_y_mm
from forcelearn.errors import ConfigError
from forcelearn.filtering import ForceFilter, ForceFilterConfig
from forcelearn.tools.experiments import filter as filter_experiment

SEEDS = range(6)
NOISE_N = 0.2


def test_filtered_error_is_under_a_third_of_the_raw_noise_on_every_seed() -> None:
    """RMS(filtered - true) <= 0.35 x raw noise std on steps and ramps, for each of 6 seeds."""
    print("\nseed  raw std N  filtered RMS N  ratio  step delays ms")
    ratios = []
    for seed in SEEDS:
        run = filter_experiment.run(seed)
        ratios.append(run.rms_ratio)
        delays = ", ".join(f"{1000 * d:.0f}" for d in run.step_delays_s)
        print(f"{seed:4d}  {run.raw_noise_std_n:9.3f}  {run.filtered_rms_error_n:14.3f}"
              f"  {run.rms_ratio:5.3f}  {delays}")
        assert run.raw_noise_std_n == pytest.approx(NOISE_N, rel=0.1)
        for height, delay in zip(filter_experiment.step_heights_n(), run.step_delays_s,
                                 strict=True):
            # steps far above the noise are followed at once; small ones by the rate model
            assert delay <= (0.001 if abs(height) > 10 * NOISE_N else 0.05)
    print(f"ratio over seeds: mean {np.mean(ratios):.3f}, max {np.max(ratios):.3f}")
    assert max(ratios) <= 0.35


def test_a_plain_constant_rate_filter_would_fail_the_bound() -> None:
    """Without the jump restart (huge gate) the profile misses the bound: the restart matters."""
    config = ForceFilterConfig(measurement_variance_n2=NOISE_N**2, jump_gate_sigma=1e9)
    assert filter_experiment.run(0, config).rms_ratio > 0.35


def test_missing_samples_are_predicted_along_the_ramp() -> None:
    """On a 100 N/s ramp, 20 missing samples are bridged by prediction, not held flat."""
    kf = ForceFilter(
        ForceFilterConfig(
            sample_period_s=0.001, measurement_variance_n2=1e-4, jump_gate_sigma=1e9
        )
    )
    for i in range(500):
        kf.update(100.0 * i * 1e-3)
    for _ in range(20):
        predicted = kf.update(None)
    assert predicted == pytest.approx(100.0 * 519 * 1e-3, abs=0.05)


def test_counter_gaps_across_the_wrap_become_predictions() -> None:
    """Counters 65000..65535, 0.., then 20 missing: the estimate keeps the ramp's time."""
    kf = ForceFilter(
        ForceFilterConfig(
            sample_period_s=0.001, measurement_variance_n2=1e-4, jump_gate_sigma=1e9
        )
    )
    counters = [(65000 + i) % 65536 for i in range(536)] + [14 + i for i in range(5)]
    times = list(range(536)) + [556 + i for i in range(5)]
    for counter, k in zip(counters, times, strict=True):
        wrench = np.array([0.0, 100.0 * k * 1e-3, 0.0, 0.0, 0.0, 0.0])
        kf.on_sample(WrenchSample(wrench, 0.0, counter))
    assert kf.force_n == pytest.approx(100.0 * 560 * 1e-3, abs=0.05)


def test_one_outlier_does_not_move_the_estimate() -> None:
    """A single 30 N spike on a steady 10 N is dropped after one sample; the track resumes."""
    rng = np.random.default_rng(1)
    kf = ForceFilter(ForceFilterConfig(measurement_variance_n2=NOISE_N**2))
    for _ in range(300):
        kf.update(10.0 + NOISE_N * rng.standard_normal())
    kf.update(30.0)
    after = [kf.update(10.0 + NOISE_N * rng.standard_normal()) for _ in range(5)]
    assert np.all(np.abs(np.array(after) - 10.0) < NOISE_N)
    assert kf.jumps == 1


def test_measurement_variance_r_sets_the_smoothing() -> None:
    """A larger R (as the calibration tool may write) smooths more: output std shrinks."""
    stds = []
    for r in (0.001, 0.04, 1.0):
        rng = np.random.default_rng(2)
        kf = ForceFilter(ForceFilterConfig(measurement_variance_n2=0.04, jump_gate_sigma=1e9))
        kf.set_measurement_variance(r)
        out = [kf.update(5.0 + NOISE_N * rng.standard_normal()) for _ in range(2000)]
        stds.append(np.std(out[500:]))
    assert stds[0] > stds[1] > stds[2]
    with pytest.raises(ValueError):
        kf.set_measurement_variance(0.0)


@pytest.mark.parametrize("key", ["sample_period_s", "measurement_variance_n2", "rate_noise_var"])
def test_config_refuses_non_positive_values(key: str) -> None:
    """Zero periods and variances are configuration errors naming the key."""
    with pytest.raises(ConfigError, match=key):
        ForceFilterConfig(**{key: 0.0})


def test_async_stream_from_the_driver_feeds_the_filter() -> None:
    """Driver (async) -> filter callback, pressing the sponge at 19.61 N: estimate within 0.1 N."""
    channel = f"jr3-filter-{os.getpid()}-{next(itertools.count())}"
    sponge = Sponge()
    physics = CellPhysics(sponge, Pose(0.0, 60.0, -40.0))  # free space while zeroing
    target_n = filter_experiment.DESIRED_N
    depth = target_n / 2.0 / (1 + 0.15 * np.cos(2 * np.pi * 60 / 120))
    kf = ForceFilter(ForceFilterConfig(sample_period_s=0.001, measurement_variance_n2=NOISE_N**2))
    white = Jr3ModelParams(emulate_filter=False)  # the stream filter's model: white noise
    with Jr3EmulatorNode(physics, channel=channel, seed=4, model=white) as node, \
            can.Bus(interface="virtual", channel=channel) as bus:
        config = Jr3Config(mode="async", period_us=1000, zero_on_init=True, zero_settle_s=0.0)
        pressed = threading.Event()
        after_press: list[float] = []
        at_done: list[float] = []  # (filtered, seen) at the 400th sample after the press

        def on_sample(sample: WrenchSample) -> None:
            kf.on_sample(sample)
            if pressed.is_set():
                after_press.append(sample.timestamp_s)
                if len(after_press) == 400:  # 0.4 s of samples at 1 kHz, however long it takes
                    # what a noiseless sensor reads now: the true force plus the bias's
                    # drift since the zero (a random walk in the cell's time, and how much
                    # of it passed before the press depends on the host's speed)
                    drift = node.model.bias[1] - node.model.offset[1]
                    at_done.extend((kf.force_n, physics.true_wrench()[1] + drift))
                    done.set()

        done = threading.Event()
        with Jr3CanSensor(bus, config, on_sample=on_sample) as sensor:
            physics.set_pose(Pose(0.0, surface_y_mm(sponge.params, 0, -40.0) - depth, -40.0))
            true_n = physics.true_wrench()[1]
            pressed.set()
            assert done.wait(30.0), "the sensor stopped streaming"
            stats = sensor.stats
        assert node.mode == "idle"
    estimate, true_now = at_done
    print(f"\nsponge: true {true_n:.3f} N at the press, {true_now:.3f} N read 0.4 s later, "
          f"filtered {estimate:.3f} N, {stats.samples} samples")
    assert true_n == pytest.approx(target_n, rel=0.01)
    assert estimate == pytest.approx(true_now, abs=0.1)


def test_a_sample_with_its_sensor_time_is_one_step_of_that_length() -> None:
    """A sample with its sensor time is one step of that length.

    A JR3 adapter's counter steps by ~8 sensor frames per 1 ms sample: with the sample's sensor time
    the stream filter makes one 1 ms step, exactly as a filter of 1 ms period fed consecutive
    counters; a filter that counted frames instead predicted 7 extra steps for every sample.
    """
    config = ForceFilterConfig(model="stream", sample_period_s=0.001)
    timed, counted = ForceFilter(config), ForceFilter(config)
    rng = np.random.default_rng(3)
    for i in range(200):
        z = 10.0 + 0.05 * i + 0.2 * rng.standard_normal()
        wrench = np.array([0.0, z, 0.0, 0.0, 0.0, 0.0])
        timed.on_sample(WrenchSample(wrench, 0.0, (8 * i) % 65536,
                                     sensor_dt_s=None if i == 0 else 8 * 125e-6))
        counted.on_sample(WrenchSample(wrench, 0.0, i))
    assert timed.force_n == pytest.approx(counted.force_n, rel=1e-12)
    assert timed.rate_n_per_s == pytest.approx(counted.rate_n_per_s, rel=1e-12)


@pytest.mark.parametrize(("axis", "sign"), [(1, 1.0), (2, -1.0), (0, -1.0)])
def test_normal_force_is_the_signed_axis_of_one_wrench_or_of_rows(axis: int,
                                                                   sign: float) -> None:
    """``normal_force``: sign x wrench[axis], the same for one wrench and for rows of them."""
    config = ForceFilterConfig(axis=axis, sign=sign)
    rows = np.random.default_rng(axis).normal(size=(5, 6))
    assert np.array_equal(config.normal_force(rows), sign * rows[:, axis])
    assert [float(config.normal_force(row)) for row in rows] == (sign * rows[:, axis]).tolist()
