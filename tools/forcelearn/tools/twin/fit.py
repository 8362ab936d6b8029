"""Fit the twin: the arm from the moves' timing, the sponge from the bursts, the sensor's noise.

The last ``HOLD_OUT`` of the trials are held out: every member of the family
(:func:`~forcelearn.tools.twin.params.family`) is fitted on the others by
:func:`scipy.optimize.least_squares` and judged by its residuals on the held-out
trials with the BIC's penalty for its parameter count. The chosen member
represents the cell when its held-out RMS on the control steps is at most
``REPRESENTED_FACTOR`` times the sensor's per-sample noise (and at least
``REPRESENTED_FLOOR_N``); otherwise the verdict says why, and no twin is written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from forcelearn.records import TrialRecords
from forcelearn.tools.twin.arm import ArmFit, emulator_delay_s, fit_arm, timed_moves
from forcelearn.tools.twin.arrays import RecordArrays, RecordsError, to_arrays
from forcelearn.tools.twin.forward import (
    Reading,
    ToolPath,
    motion_shape,
    predict_means,
)
from forcelearn.tools.twin.params import BY_NAME, Member, family
from forcelearn.tools.twin.sensor import SensorFit, fit_sensor
from forcelearn.tools.twin.uncertainty import sigmas

HOLD_OUT = 0.2
"""Share of the trials (the last ones) the fit does not use."""
MIN_TRIALS = 5
REPRESENTED_FACTOR = 2.0
"""Held-out RMS at most this many times the sensor's per-sample noise: represented."""
REPRESENTED_FLOOR_N = 0.05
"""...and never a stricter bar than this, N (a noiseless cell)."""
BURST_FLOOR_N = 0.02
"""Floor of a burst mean's expected scatter in the weights, N."""


BIC_RESOLUTION = 0.25
"""Weighted residuals (in units of a burst's expected scatter) below this are not told apart:
on a (near) noiseless cell two members that both fit to this are equal, and the simpler wins."""
BIC_MARGIN = 10.0
"""ΔBIC (held-out trials) a richer member must win by to be chosen (Kass & Raftery 1995: over
10 is very strong evidence); within it, the simpler member is kept."""

@dataclass
class MemberFit:
    """One member fitted: values and 1-sigma uncertainties, residuals, score."""

    member: Member
    values: dict[str, float]
    sigmas: dict[str, float]
    train_rms_n: float
    heldout_rms_n: float
    """RMS of the control steps' burst means on the held-out trials, N."""
    bic: float
    free: int
    held: tuple[str, ...] = ()
    """Parameters the records did not determine, held at the base config's value."""


@dataclass
class TwinFit:
    """Everything the report and the twin's config need."""

    sponge: dict[str, float]
    """The chosen member's sponge (every SpongeParams field)."""
    chosen: MemberFit
    members: list[MemberFit]
    arm: ArmFit
    arm_emulator_delay_s: float
    """The fitted command-to-motion delay as the emulator's arm needs it, s."""
    base_start_delay_s: float
    sensor: SensorFit
    train: RecordArrays
    heldout: RecordArrays
    heldout_predicted: np.ndarray
    threshold_n: float
    represented: bool
    reason: str
    diagnostics: list[str] = field(default_factory=list)

    @property
    def train_trials(self) -> int:
        """Trials the fit used."""
        return self.train.trials


def split(data: RecordArrays) -> tuple[RecordArrays, RecordArrays]:
    """The first 80 % of trials to fit, the last 20 % held out."""
    if data.trials < MIN_TRIALS:
        raise RecordsError(
            f"the records hold {data.trials} trials; the fit needs at least {MIN_TRIALS} "
            f"(it holds out the last {HOLD_OUT:.0%}): run more trials"
        )
    held = max(1, round(HOLD_OUT * data.trials))
    order = np.arange(data.trials)
    return data.rows(order[:-held]), data.rows(order[-held:])


def _weights(data: RecordArrays, noise_n: float) -> np.ndarray:
    """1 / expected scatter of each burst mean (T, M); 0 where no burst."""
    noise = noise_n if math.isfinite(noise_n) else 0.0
    spread = np.sqrt(noise**2 / np.maximum(data.count, 1.0) + BURST_FLOOR_N**2)
    return np.where(data.has_burst, 1.0 / spread, 0.0)


def initial_sponge(data: RecordArrays, base: dict[str, float], reading: Reading
                   ) -> dict[str, float]:
    """Stiffness, surface and slope from a straight line through the contact bursts."""
    start = dict(base)
    contact = data.has_burst & data.is_step & (data.mean_n > 0.5)
    if contact.sum() < 3:
        return start
    z, y = data.reached[..., 2][contact], data.reached[..., 1][contact]
    force = data.mean_n[contact] / max(abs(reading.along_y), 1e-6)
    travelled = base["z_top_mm"] - z
    design = np.column_stack([np.ones_like(z), travelled, -y])
    (a, b, k), *_ = np.linalg.lstsq(design, force, rcond=None)
    if k > 0:
        start.update(stiffness_n_per_mm=float(k), surface_y_mm=float(a / k),
                     surface_slope=float(np.clip(b / k, -0.4, 0.4)))
    return start


TIME_SCALES = ("softening_passes", "set_passes", "waviness_wavelength_mm",
               "stiffness_wavelength_mm", "relaxation_time_s", "hysteresis_depth_mm")
"""Parameters that set a scale (passes, mm, s) for an amplitude: held first when loose."""
HOLD_ROUNDS = 3
HOLD_COST = 1.02
"""Holding loose parameters at the base values is kept only if the fit's cost rises less than
this factor (else the records need them: they stay fitted, reported as not determined)."""


def fit_member(member: Member, train: RecordArrays, heldout: RecordArrays,
               start: dict[str, float], base: dict[str, float], arm: dict[str, float],
               reading: Reading, noise_n: float) -> MemberFit:
    """Fit one member's free parameters on ``train``; score it on ``heldout``.

    A parameter the records do not determine is held at the base config's value
    and the rest refitted (scales such as a wear's time constant first, so the
    amplitude the records do show, e.g. the start of a wear curve, is still fitted),
    unless holding it makes the fit worse (``HOLD_COST``): then the records need it
    and it keeps its fitted value, reported as not determined.
    """
    fixed = dict(member.fixed)
    values = {**start, **fixed}
    free = [n for n in member.free if n not in fixed]
    held: list[str] = []
    held_sigmas: dict[str, float] = {}
    weights = _weights(train, noise_n)
    use = train.has_burst
    groups = np.broadcast_to(train.trial[:, None], use.shape)[use]
    shape = motion_shape(train, arm)
    path = ToolPath(train, arm)
    spread: dict[str, float] = {}
    cost = math.inf
    kept: tuple[dict[str, float], list[str], list[str], dict[str, float]] = (
        values, free, held, held_sigmas)
    for _ in range(HOLD_ROUNDS):
        names = list(free)
        low = np.array([BY_NAME[n].low for n in names])
        high = np.array([BY_NAME[n].high for n in names])
        x0 = np.clip(np.array([values[n] for n in names]), low + 1e-6 * (high - low),
                     high - 1e-6 * (high - low))
        frozen = dict(values)

        def residuals(x: np.ndarray, names: list[str] = names,
                      frozen: dict[str, float] = frozen) -> np.ndarray:
            sponge = {**frozen, **dict(zip(names, x.tolist(), strict=True))}
            predicted = predict_means(train, sponge, arm, reading, shape, path)
            error: np.ndarray = ((predicted - train.mean_n) * weights)[use]
            return error

        result = least_squares(residuals, x0, bounds=(low, high), x_scale="jac",
                               method="trf", max_nfev=100 * len(names))
        if held and result.cost > HOLD_COST * cost:
            # holding them made the fit worse: the records need them free (undetermined)
            values, free, held, held_sigmas = kept
            break
        cost = float(result.cost)
        values.update(zip(names, result.x.tolist(), strict=True))
        spread = dict(zip(names, sigmas(result.jac, result.fun, groups).tolist(),
                          strict=True))
        loose = [n for n in names if not BY_NAME[n].determined(values[n], spread[n])]
        if not loose:
            break
        scales = [n for n in loose if n in TIME_SCALES]
        hold = scales or loose
        if len(hold) == len(names):
            break
        kept = (dict(values), list(free), list(held), dict(held_sigmas))
        for n in hold:
            values[n] = base[n]
            held.append(n)
            held_sigmas[n] = spread[n]  # its uncertainty when it was last fitted
        free = [n for n in free if n not in hold]
    spread.update(held_sigmas)
    train_pred = predict_means(train, values, arm, reading, shape, path)
    held_pred = predict_means(heldout, values, arm, reading)
    train_rms = _rms(train_pred - train.mean_n, train.is_step & train.has_burst)
    held_res = ((held_pred - heldout.mean_n) * _weights(heldout, noise_n))[heldout.has_burst]
    n_held = max(1, held_res.size)
    mse = max(float(np.mean(held_res**2)), BIC_RESOLUTION**2)
    bic = n_held * math.log(mse) + len(free) * math.log(n_held)
    return MemberFit(
        member, values, {n: float(spread[n]) for n in member.free if n not in fixed},
        train_rms, _rms(held_pred - heldout.mean_n, heldout.is_step & heldout.has_burst), bic,
        len(free), tuple(held),
    )


def _rms(residuals: np.ndarray, mask: np.ndarray) -> float:
    values = residuals[mask & np.isfinite(residuals)]
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan


def _diagnose(train: RecordArrays, predicted: np.ndarray, values: dict[str, float]) -> list[str]:
    """What the residuals say the model misses (depth trend, press vs ease-off, per trial)."""
    notes: list[str] = []
    use = train.is_step & train.has_burst & np.isfinite(predicted)
    if use.sum() < 10:
        return notes
    residual = (train.mean_n - predicted)[use]
    force = predicted[use]
    if np.std(force) > 0:
        curve = np.polyfit(force, residual, 2)
        bend = np.polyval(curve, force)
        share = float(np.var(bend) / max(np.var(residual), 1e-300))
        if share > 0.3:
            notes.append(
                f"{share:.0%} of the residual is a curve in the force (the force does not "
                "grow linearly with depth: a nonlinear foam)"
            )
    dy = np.diff(train.commanded[..., 1], axis=1, prepend=np.nan)[use]
    pressing, easing = residual[dy < 0], residual[dy > 0]
    if pressing.size > 5 and easing.size > 5:
        gap = float(np.mean(pressing) - np.mean(easing))
        if abs(gap) > 3 * float(np.std(residual)) / math.sqrt(min(pressing.size, easing.size)):
            notes.append(
                f"steps pressing in read {gap:+.2f} N more than steps easing off, beyond the "
                "model's relaxation (hysteresis)"
            )
    return notes


def fit_twin(records: list[TrialRecords], base_sponge: dict[str, float],
             base_arm: dict[str, float], reading: Reading, band_mm: float, tick_s: float,
             calibration_noise_n: float | None = None,
             members: tuple[Member, ...] | None = None,
             configured_phi: float | None = None) -> TwinFit:
    """Fit every part of the twin to a run's records (trials in order).

    ``configured_phi`` is the AR(1) coefficient per burst sample the run's sensor
    settings give the noise (the adapter's low-pass; 0 for white noise): it
    corrects the noise measured within bursts. ``calibration_noise_n`` replaces
    that measurement by a calibration's.

    Raises:
        RecordsError: too few trials, or records that cannot be fitted.
    """
    records = sorted(records, key=lambda t: t.trial)
    data = to_arrays(records)
    train, heldout = split(data)
    arm = fit_arm(train, base_arm, band_mm)
    distances, _ = timed_moves(train)
    delay = base_arm["start_delay_s"]
    if math.isfinite(arm.sigmas["start_delay_s"]):
        delay = emulator_delay_s(arm.values, distances, band_mm, tick_s)
    first = fit_sensor(records, train, None, calibration_noise_n, configured_phi)
    start = initial_sponge(train, base_sponge, reading)
    fits = [fit_member(m, train, heldout, start, base_sponge, arm.values, reading,
                       first.noise_n) for m in (members or family())]
    best = min(f.bic for f in fits)
    # Parsimony: the simplest member (family order) whose BIC is within BIC_MARGIN of the
    # best; a richer law must explain the held-out trials clearly better, not by rounding.
    chosen = next(f for f in fits if f.bic <= best + BIC_MARGIN)
    train_pred = predict_means(train, chosen.values, arm.values, reading)
    sensor = fit_sensor(records, train, train_pred - train.mean_n, calibration_noise_n,
                        configured_phi)
    held_pred = predict_means(heldout, chosen.values, arm.values, reading)
    noise = sensor.noise_n if math.isfinite(sensor.noise_n) else 0.0
    threshold = max(REPRESENTED_FACTOR * noise, REPRESENTED_FLOOR_N)
    represented = chosen.heldout_rms_n <= threshold
    diagnostics = _diagnose(train, train_pred, chosen.values)
    if represented:
        reason = (f"held-out RMS {chosen.heldout_rms_n:.3f} N is within {threshold:.3f} N "
                  f"({REPRESENTED_FACTOR:g} x the sensor's noise, at least "
                  f"{REPRESENTED_FLOOR_N} N)")
    else:
        reason = (f"the best member ({chosen.member.name}) predicts the held-out trials with "
                  f"an RMS of {chosen.heldout_rms_n:.3f} N, above {threshold:.3f} N "
                  f"({REPRESENTED_FACTOR:g} x the sensor's noise of {noise:.3f} N)")
        if diagnostics:
            reason += "; " + "; ".join(diagnostics)
    return TwinFit(chosen.values, chosen, fits, arm, delay, base_arm["start_delay_s"], sensor,
                   train, heldout, held_pred,
                   threshold, represented, reason, diagnostics)
