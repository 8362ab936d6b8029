"""The force-filter experiment: a step-and-ramp force through the emulated JR3, filtered.

The true force is scripted (steps as the roller meets the sponge or the robot
steps, ramps as it travels over a sloping surface), put through the shared
cell physics and the emulator's sensor model (noise, quantisation), scaled back
to newtons as the driver does, and filtered. Bias and drift are off: removing
them is zeroing's and calibration's job, not the filter's.

Used by the tests (tests/filtering) and by ``plot_filter`` for the figure.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams, Jr3SensorModel
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.filtering import ForceFilter, ForceFilterConfig
from forcelearn.protocols.jr3_can.scaling import counts_to_wrench

SAMPLE_PERIOD_S = 0.001
DURATION_S = 6.0
DESIRED_N = 19.61  # the paper's 2 kgf

# (time s, force N): piecewise linear; a repeated time is a step
PROFILE_KNOTS: tuple[tuple[float, float], ...] = (
    (0.0, 0.0), (0.5, 0.0),
    (0.5, 10.0), (1.0, 10.0),                    # contact: step to 10 N
    (2.0, DESIRED_N), (2.5, DESIRED_N),          # ramp to the paper's 19.61 N
    (2.5, DESIRED_N + 0.8), (3.0, DESIRED_N + 0.8),  # a small step (4 noise sigma)
    (3.0, 15.0), (3.5, 15.0),                    # robot steps back
    (4.5, 25.0),                                 # ramp up over a sloping surface
    (4.5, DESIRED_N), (5.5, DESIRED_N),
    (5.5, 0.0), (DURATION_S, 0.0),               # lift off
)


def step_times_s() -> list[float]:
    """Times of the profile's steps."""
    return [a[0] for a, b in itertools.pairwise(PROFILE_KNOTS) if a[0] == b[0]]


def step_heights_n() -> list[float]:
    """Heights (N, signed) of the profile's steps, in the order of :func:`step_times_s`."""
    return [b[1] - a[1] for a, b in itertools.pairwise(PROFILE_KNOTS) if a[0] == b[0]]


def force_profile_n(t_s: float) -> float:
    """The scripted true normal force (N) at time ``t_s``; right-continuous at steps."""
    for (t0, f0), (t1, f1) in itertools.pairwise(PROFILE_KNOTS):
        if t0 <= t_s < t1:
            return f0 + (f1 - f0) * (t_s - t0) / (t1 - t0)
    return PROFILE_KNOTS[-1][1]


class ScriptedContact:
    """A contact environment whose force (N, world frame) the experiment sets each sample."""

    def __init__(self) -> None:
        self.force_world_n = np.zeros(3)

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        """Return the scripted force, wherever the tool is."""
        return self.force_world_n


@dataclass(frozen=True)
class FilterRun:
    """One run: time (s), true, raw and filtered force (N), and the figures of merit."""

    t_s: np.ndarray
    true_n: np.ndarray
    raw_n: np.ndarray
    filtered_n: np.ndarray
    raw_noise_std_n: float
    filtered_rms_error_n: float
    step_delays_s: tuple[float, ...]

    @property
    def rms_ratio(self) -> float:
        """Filtered RMS error over the raw noise standard deviation."""
        return self.filtered_rms_error_n / self.raw_noise_std_n


def quiet_drift_model(base: Jr3ModelParams | None = None) -> Jr3ModelParams:
    """The sensor model with bias and drift off (noise and quantisation kept)."""
    base = base or Jr3ModelParams()
    return Jr3ModelParams(
        full_scales=base.full_scales, noise_std=base.noise_std, initial_bias=(0.0,) * 6,
        bias_drift_per_sqrt_s=(0.0,) * 6, zero_average_samples=base.zero_average_samples,
        sync_sample_period_s=SAMPLE_PERIOD_S,
    )


def run(seed: int, config: ForceFilterConfig | None = None,
        model: Jr3ModelParams | None = None) -> FilterRun:
    """Run the experiment once with the sensor noise seeded by ``seed``."""
    model_params = quiet_drift_model(model)
    config = config or ForceFilterConfig(
        sample_period_s=SAMPLE_PERIOD_S, measurement_variance_n2=model_params.noise_std[1] ** 2
    )
    contact = ScriptedContact()
    physics = CellPhysics(contact)
    sensor = Jr3SensorModel(model_params, np.random.default_rng(seed))
    kf = ForceFilter(config)
    full_scales = np.asarray(model_params.full_scales)
    n = round(DURATION_S / SAMPLE_PERIOD_S)
    t = np.arange(n) * SAMPLE_PERIOD_S
    true_n, raw_n, filtered_n = np.empty(n), np.empty(n), np.empty(n)
    for i, ti in enumerate(t):
        contact.force_world_n = np.array([0.0, force_profile_n(ti), 0.0])
        wrench = physics.true_wrench()
        raw = counts_to_wrench(np.array(sensor.measure(wrench, SAMPLE_PERIOD_S)), full_scales)
        true_n[i], raw_n[i] = wrench[1], raw[1]
        filtered_n[i] = kf.update(raw[1])
    return FilterRun(
        t_s=t, true_n=true_n, raw_n=raw_n, filtered_n=filtered_n,
        raw_noise_std_n=float(np.std(raw_n - true_n)),
        filtered_rms_error_n=float(np.sqrt(np.mean((filtered_n - true_n) ** 2))),
        step_delays_s=tuple(_step_delay_s(t, filtered_n, ts) for ts in step_times_s()),
    )


def _step_delay_s(t: np.ndarray, filtered: np.ndarray, step_s: float) -> float:
    """Time from a step until the estimate is within 10 % of the step height of the new level."""
    before = force_profile_n(step_s - 1e-9)
    after = force_profile_n(step_s)
    i0 = int(np.searchsorted(t, step_s - 1e-9))
    close = np.abs(filtered[i0:] - after) <= 0.1 * abs(after - before)
    return float(t[i0 + int(np.argmax(close))] - t[i0]) if close.any() else float("inf")
