"""The twin's fit: its model, recovery, stability and verdict."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from forcelearn.emulators.physics.arm_motion import MotionParams
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.tools.twin import fit as fitting
from forcelearn.tools.twin import forward
from forcelearn.tools.twin.arrays import RecordsError, to_arrays
from forcelearn.tools.twin.fit import TwinFit, fit_twin
from forcelearn.tools.twin.params import BY_NAME, family
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

READING = forward.Reading.of(DOWN, 1, -1.0)
BASE_ARM = base_arm()  # the emulator's defaults
TRUTH = SpongeParams(
    surface_y_mm=0.6, surface_slope=0.02, waviness_mm=0.7, stiffness_n_per_mm=3.2,
    stiffness_variation=0.1, softening=0.3, softening_passes=25.0, set_mm=1.5, set_passes=20.0,
    relaxation_ratio=0.4, relaxation_time_s=0.3,
)


def _base() -> dict[str, float]:
    return {k: float(v) for k, v in dataclasses.asdict(SpongeParams()).items()}


RUN = SimulatedRun()
COLOUR = math.exp(-2 * math.pi * RUN.cutoff_hz * RUN.sample_period_s)
"""The adapter low-pass's AR(1) coefficient per sample of the simulated bursts."""


def _fit(records: list[TrialRecords]) -> TwinFit:
    return fit_twin(records, _base(), BASE_ARM, READING, 0.1, 0.004, configured_phi=COLOUR)


@pytest.fixture(scope="module")
def noiseless() -> TwinFit:
    """The fit of a noiseless cell whose sponge is not the default one."""
    return _fit(simulate_run(SimulatedRun(trials=25, sponge=TRUTH), seed=3))


def _true_arm(motion: MotionParams) -> dict[str, float]:
    return {"start_delay_s": motion.start_delay_s, "accel_mm_s2": motion.accel_mm_s2,
            "default_speed_mm_s": motion.speed_mm_s, "lag_s": motion.lag_s,
            "in_position_mm": motion.in_position_mm}


def _errors(sponge: SpongeParams, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The model's |error| (N) on every burst of a short emulated run; also without the terms.

    The second array is the model without hysteresis and friction on the same records.
    """
    motion = MotionParams()
    records = simulate_run(SimulatedRun(trials=4, steps=10, burst_samples=5, sponge=sponge,
                                        motion=motion, exploration_mm=2.0), seed=seed)
    data = to_arrays(records)
    predicted = forward.predict_means(data, sponge, _true_arm(motion), READING)
    without = forward.predict_means(
        data, dataclasses.replace(sponge, hysteresis_loss=0.0, friction_coefficient=0.0),
        _true_arm(motion), READING)
    return (np.abs(predicted - data.mean_n)[data.has_burst],
            np.abs(without - data.mean_n)[data.has_burst])


@pytest.mark.parametrize("terms", [
    {"hysteresis_loss": 0.2, "relaxation_ratio": 0.0},
    {"friction_coefficient": 0.4, "surface_slope": 0.12, "relaxation_ratio": 0.0},
    {"hysteresis_loss": 0.25, "friction_coefficient": 0.3, "stiffening_exponent": 1.3,
     "relaxation_ratio": 0.0},
    {"hysteresis_loss": 0.15, "friction_coefficient": 0.3},
])
def test_forward_model_follows_hysteresis_and_friction_on_recorded_moves(
    terms: dict[str, float],
) -> None:
    """Recorded bursts of a hysteretic, frictional emulated sponge, move by move.

    The model's error on them is within 0.025 N at worst (0.005 N RMS) of its error on the
    same cell without the two terms (what the relaxation's and the arm's approximations
    leave: ~0.006 N elastic since the arm model is the emulator's tick-grid motion), while
    the terms move the force by > 0.5 N. The worst burst is the sampled path's (4 pieces a
    move for the Dahl state: 0.021 N above the baseline on the stiffening foam, 0.018 N
    with 6 pieces).
    """
    error, ignored = _errors(SpongeParams(**terms), seed=2)
    plain = {**terms, "hysteresis_loss": 0.0, "friction_coefficient": 0.0}
    baseline, _ = _errors(SpongeParams(**plain), seed=2)
    assert error.max() < baseline.max() + 0.025
    assert np.sqrt(np.mean(error**2)) < np.sqrt(np.mean(baseline**2)) + 0.005
    assert ignored.max() > 0.5


@pytest.mark.parametrize(("wavelength_mm", "z_step_mm"), [(40.0, -10.0), (30.0, -10.0)])
def test_the_relaxing_part_follows_a_short_waviness_within_a_move(
        wavelength_mm: float, z_step_mm: float) -> None:
    """A 2 mm waviness over 30-40 mm under 10 mm steps: the depth bends within each move.

    The relaxing part integrates the foam depth's changes along the move; taken on the
    straight line between the two ends' depths (the model before 2026-12-05) the error was
    0.046-0.064 N RMS, up to 0.13 N; with the surface under the tool at every point it is
    the relaxation's and the arm's approximations' (~0.003 N RMS, as on the default shapes).
    """
    sponge = SpongeParams(waviness_mm=2.0, waviness_wavelength_mm=wavelength_mm,
                          relaxation_ratio=0.4, relaxation_time_s=0.3)
    motion = MotionParams()
    records = simulate_run(SimulatedRun(trials=4, steps=20, burst_samples=5, sponge=sponge,
                                        motion=motion, z_step_mm=z_step_mm,
                                        exploration_mm=0.5), seed=2)
    data = to_arrays(records)
    error = (forward.predict_means(data, sponge, _true_arm(motion), READING)
             - data.mean_n)[data.has_burst]
    assert np.sqrt(np.mean(error**2)) < 0.008
    assert np.abs(error).max() < 0.02


def test_a_trial_starts_with_the_relaxing_part_the_last_retreat_left() -> None:
    """A foam relaxing by 0.56 over 0.53 s, pressed 45 mm deep in 8 mm steps by a fast arm.

    The retreat that ends a trial eases the foam off, and out of contact the emulated sponge
    zeroes a positive relaxing part only: the foam is still recovering when the next trial
    presses in. A model that started every trial relaxed read the next trial's first
    contacts up to 0.155 N high (16 % of a 0.95 N burst; hidden cell 02 of seed 6's probe
    and trials); carried over, within 0.01 N.
    """
    sponge = SpongeParams(surface_y_mm=-1.31, thickness_mm=80.0, stiffness_n_per_mm=0.657,
                          softening=0.18, softening_passes=31.0, set_mm=1.18, set_passes=20.8,
                          relaxation_ratio=0.565, relaxation_time_s=0.533,
                          stiffening_exponent=1.149)
    motion = dataclasses.replace(MotionParams(), accel_mm_s2=2820.0, lag_s=0.028)
    records = simulate_run(SimulatedRun(trials=3, steps=8, burst_samples=5, sponge=sponge,
                                        motion=motion, max_step_mm=8.13,
                                        start_mm=(900.0, -18.6, 0.0), retract_y_mm=13.0,
                                        desired_force_n=29.36), seed=2)
    data = to_arrays(records)
    error = (forward.predict_means(data, sponge, _true_arm(motion), READING)
             - data.mean_n)[data.has_burst]
    assert np.abs(error).max() < 0.01


@pytest.mark.long
def test_fit_recovers_hysteresis_and_friction() -> None:
    """A noiseless hysteretic foam under a frictional roller: h and mu within a few %."""
    truth = dataclasses.replace(TRUTH, hysteresis_loss=0.15, friction_coefficient=0.4,
                                surface_slope=0.1)
    records = simulate_run(SimulatedRun(trials=10, steps=12, burst_samples=10, sponge=truth),
                           seed=3)
    # the default family: this reading sees friction only through the slope
    fit = fit_twin(records, _base(), BASE_ARM, READING, 0.1, 0.004, configured_phi=COLOUR)
    assert fit.represented
    assert fit.chosen.member.name == "hysteretic+friction"
    values = fit.chosen.values
    assert values["hysteresis_loss"] == pytest.approx(0.15, rel=0.02)
    assert values["friction_coefficient"] == pytest.approx(0.4, rel=0.05)
    assert values["stiffness_n_per_mm"] == pytest.approx(3.2, rel=0.02)
    for name in ("hysteresis_loss", "friction_coefficient"):
        assert BY_NAME[name].determined(values[name], fit.chosen.sigmas[name]), name
    assert fit.chosen.heldout_rms_n < 0.05


class _Walked(Exception):
    """Stops a fit once its members are known."""


def test_friction_is_fitted_for_a_reading_along_the_normal(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The §5 tool reads along the surface's normal; the fit still walks the friction member.

    The surface's tilt shows a roller's friction there at a few % of N: left out, it went
    into the relaxation on seed 2's hidden cells (cell 27: ratio +16 %, time -38 %).
    """
    walked: list[str] = []

    def members_only(members: tuple[object, ...], *args: object, **kwargs: object) -> None:
        walked.extend(m.name for m in members)  # type: ignore[attr-defined]
        raise _Walked

    monkeypatch.setattr(fitting, "fit_nested", members_only)
    records = simulate_run(SimulatedRun(trials=6, steps=6, burst_samples=5,
                                        sponge=dataclasses.replace(TRUTH,
                                                                   friction_coefficient=0.3)),
                           seed=1)
    with pytest.raises(_Walked):
        _fit(records)
    assert READING.along_z == pytest.approx(0.0, abs=1e-12)
    assert walked == [m.name for m in family()]
    assert walked[-1] == "hysteretic+friction"


def test_a_cell_without_hysteresis_keeps_a_simpler_member(noiseless: TwinFit) -> None:
    """Parsimony: the hysteretic members are fitted and find h near 0; the linear one wins."""
    fitted = {m.member.name: m for m in noiseless.members}
    assert "hysteretic" in fitted and "hysteretic+friction" in fitted
    assert fitted["hysteretic"].values["hysteresis_loss"] < 0.01
    assert noiseless.chosen.member.name == "linear"
    assert noiseless.sponge["hysteresis_loss"] == 0.0
    assert noiseless.sponge["friction_coefficient"] == 0.0


def test_fit_recovers_a_noiseless_cell(noiseless: TwinFit) -> None:
    """Every determined sponge parameter within 3 % (or its absolute bound x 3) of the truth."""
    fit = noiseless
    assert fit.represented
    assert fit.chosen.member.name == "linear"
    values, truth = fit.chosen.values, dataclasses.asdict(TRUTH)
    assert values["stiffness_n_per_mm"] == pytest.approx(truth["stiffness_n_per_mm"], rel=0.02)
    assert values["surface_y_mm"] == pytest.approx(truth["surface_y_mm"], abs=0.15)
    assert values["surface_slope"] == pytest.approx(truth["surface_slope"], abs=0.002)
    assert values["waviness_mm"] == pytest.approx(truth["waviness_mm"], rel=0.03)
    assert values["relaxation_ratio"] == pytest.approx(truth["relaxation_ratio"], rel=0.08)
    assert values["relaxation_time_s"] == pytest.approx(truth["relaxation_time_s"], rel=0.08)
    assert values["set_mm"] == pytest.approx(truth["set_mm"], rel=0.1)
    assert values["softening"] == pytest.approx(truth["softening"], rel=0.1)
    assert fit.chosen.heldout_rms_n < 0.05
    assert fit.arm_emulator_delay_s == pytest.approx(0.05, abs=0.006)
    assert fit.arm.values["accel_mm_s2"] == pytest.approx(1000.0, rel=0.1)


def test_a_twin_of_a_twin_is_stable(noiseless: TwinFit) -> None:
    """Emulate the fitted cell with the same commands' rule, refit: the same parameters."""
    fields = {f.name for f in dataclasses.fields(SpongeParams)}
    twin = SpongeParams(**{k: v for k, v in noiseless.sponge.items() if k in fields})
    again = _fit(simulate_run(SimulatedRun(trials=25, sponge=twin), seed=3))
    for name in ("stiffness_n_per_mm", "surface_y_mm", "relaxation_ratio", "set_mm",
                 "softening", "waviness_mm", "stiffness_variation"):
        first, second = noiseless.chosen.values[name], again.chosen.values[name]
        assert second == pytest.approx(first, rel=0.03, abs=0.02), name


class _SaturatingFoam(Sponge):
    """A foam whose force saturates with depth: outside the twin's family."""

    def contact_force_world_n(self, position_mm: np.ndarray) -> np.ndarray:
        depth = self._penetration_mm(position_mm)
        return np.array([0.0, 30.0 * math.tanh(depth / 6.0), 0.0])


@pytest.mark.long
def test_records_the_family_cannot_explain_are_not_represented() -> None:
    """A saturating force law: the verdict says so and the bar is missed."""
    noisy = noise_only_sensor(0.05)
    run = SimulatedRun(trials=20, sensor=noisy, exploration_mm=2.0)
    fit = _fit(simulate_run(run, seed=1, sponge=_SaturatingFoam(run.sponge)))
    assert not fit.represented
    assert fit.chosen.heldout_rms_n > fit.threshold_n
    assert "above" in fit.reason


def test_the_noise_is_measured_from_the_bursts() -> None:
    """0.3 N of coloured adapter noise is measured within 10 %."""
    noisy = noise_only_sensor(0.3)
    fit = _fit(simulate_run(SimulatedRun(trials=10, sponge=TRUTH, sensor=noisy), seed=2))
    assert fit.sensor.noise_n == pytest.approx(0.3, rel=0.1)
    assert fit.represented


def _record(mean: float) -> StepRecord:
    move = MoveRecord((900.0, -5.0, -5.0), (900.0, -5.0, -5.0), 1.0, 1.2, 1.25)
    return StepRecord(1, 1, "step", move, BurstRecord(mean, 0.1, mean, mean, 40, 1.25, 0.005,
                                                       mean))


def test_a_damaged_record_is_a_typed_error() -> None:
    """A NaN in a record, or no trial at all: RecordsError that says what to do."""
    with pytest.raises(RecordsError, match="damaged"):
        to_arrays([TrialRecords(1, [_record(float("nan"))])])
    with pytest.raises(RecordsError, match="nothing to fit"):
        to_arrays([])


def test_too_few_trials_say_how_many_are_needed() -> None:
    """Fewer than five trials: the error names the least count."""
    records = [TrialRecords(i, [_record(5.0)]) for i in range(1, 4)]
    with pytest.raises(RecordsError, match="at least 5"):
        _fit(records)
