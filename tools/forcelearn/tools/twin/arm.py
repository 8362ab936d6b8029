"""The arm's part of the twin: delay, acceleration, speed and lag from the moves' timing.

Each recorded move gives the time from its command to in position; the model
(:func:`forcelearn.tools.twin.forward.predict_in_position_s`) is fitted by
least squares.

In-position detection latency: the driver learns "in position" by polling
(the computer link: READ_STATUS back to back, one exchange every ~44 ms at
9600 baud; EGM: every feedback message). The recorded in-position time is the
first poll that saw it, so it is the true time plus a latency in
``[0, period)``: taken as uniform, it adds ``period / 2`` to the expected time
and ``period / sqrt(12)`` to its scatter (:func:`fit_arm`), and the motion the
force model follows ends before the recorded time (:func:`with_true_in_position`).
The period comes from the records themselves (:func:`detection_period_s`: the
settle dwells are whole numbers of polls), with the link's own exchange time
(:func:`poll_guess_s`) to count them. The model is the emulator's own tick-grid motion
(:mod:`forcelearn.tools.twin.arm_model`); where the moves determine the arm, the windows
also place each move on the controller's own tick (:func:`with_grid`,
:mod:`forcelearn.tools.twin.tick_grid`). :func:`emulator_delay_s` checks the fitted delay
on the emulator's :class:`~forcelearn.emulators.physics.arm_motion.ArmMotion` (it was the
continuous model's few ms of tick-grid offset; now a fraction of a ms).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize
from scipy.special import ndtr

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.site.kinds import Polling as Polling  # re-exported: the twin's name for it
from forcelearn.site.kinds import RobotConfig, robot_kind_of
from forcelearn.site.kinds import UnmodelledKind as UnmodelledKind
from forcelearn.tools.twin import arm_model
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.forward import predict_in_position_s
from forcelearn.tools.twin.params import ARM, BY_NAME
from forcelearn.tools.twin.tick_grid import TickGrid, fit_grid, whole_ticks
from forcelearn.tools.twin.uncertainty import sigmas

MIN_MOVES = 8
"""Fewer timed moves than this: the arm keeps the base config's values."""
RMS_LIMIT_S = 0.008
"""The timing model must explain the moves to within this RMS (two 4 ms interpolation
ticks) for any arm parameter to count as determined: above it the recorded times hold
what the model lacks (a link's polling, a controller's queue), which would bias them."""


@dataclass(frozen=True)
class ArmFit:
    """The fitted arm (values and 1-sigma uncertainties by name) and its residual, s."""

    values: dict[str, float]
    sigmas: dict[str, float]
    rms_s: float
    moves: int
    note: str = ""
    """Why the arm's parameters are not determined, when none is."""
    period_s: float = 0.0
    """The in-position detection period the fit took the recorded times to carry, s."""
    timing: dict[str, float] | None = None
    """The fitted arm whose times explain the moves (each within its polling window, to
    ``RMS_LIMIT_S``) even where single parameters trade off; None when none does."""
    free_sigmas: dict[str, float] = dataclasses.field(default_factory=dict)
    """1-sigma of the held parameters when they were last free (with the polling's worst
    case): the uncertainty the report gives for a held value."""
    answer_s: float = 0.0
    """From a poll's recorded stamp to the driver holding the answer, s: a burst read after
    a wait begins this much after its recorded start (:meth:`Polling.answer_s`)."""
    grid: TickGrid | None = None
    """The controller's tick grid the recorded windows place the moves on (:func:`with_grid`);
    None: each move's in-position is the timing model's mean over the grid's phase."""


def polling_of(robot: RobotConfig, arm: ArmConfig | None = None) -> Polling:
    """How often the driver sees the robot's state while it waits: its kind's model.

    The computer link: one READ_STATUS exchange at the line's character time;
    EGM: the feedback's sample period (:meth:`~forcelearn.site.kinds.RobotKind.polling`).

    Raises:
        UnmodelledKind: the robot's kind gives no polling model (the twin cannot fit it).
    """
    return robot_kind_of(robot).polling(robot, arm or ArmConfig())


def poll_guess_s(robot: RobotConfig, arm: ArmConfig | None = None) -> float:
    """One poll's time from the config, s (:func:`polling_of`)."""
    return polling_of(robot, arm).period_s


def detection_period_s(data: RecordArrays, guess_s: float) -> float:
    """The poll period the records show, s (``guess_s`` when they show none).

    A settled move's dwell (``settled_s - in_position_s``, both poll times of one
    wait) is a whole number of polls: counted with ``guess_s``, the median dwell
    per poll is the period.
    """
    if not (math.isfinite(guess_s) and guess_s > 0):
        return 0.0
    use = data.valid & np.isfinite(data.settled_s) & np.isfinite(data.in_position_s)
    dwell = (data.settled_s - data.in_position_s)[use]
    dwell = dwell[dwell > 0.5 * guess_s]
    if dwell.size == 0:
        return guess_s
    polls = np.maximum(1.0, np.round(dwell / guess_s))
    return float(np.median(dwell / polls))


def chained_offsets_s(data: RecordArrays) -> np.ndarray:
    """(T, M) how long after its recorded start each burst began, s (0 for most).

    A burst's recorded start is the end of the wait before it. Bursts read one after
    another with no wait between (the probe's reads at contact: its approach's, then the
    press's early and relaxed reads) share that start, and each began when the one before
    had ended: that one's samples' time, ``span * count / (count - 1)`` (the emulated JR3 on
    a low-noise copy of hidden cell 25 of seed 7: 25 samples over 23.9 ms took 24.6 ms, 16
    over 15.0 ms took 16.0 ms). Taken at the shared start, the probe's third read at each
    contact was put 40 ms early, and the move after it was commanded 40 ms later than
    :func:`command_s` had it.
    """
    span = np.nan_to_num(data.burst_span_s)
    count = data.count.astype(float)
    period = np.where(count > 1, span / np.maximum(count - 1.0, 1.0), np.nan)
    known = np.isfinite(period) & data.has_burst
    typical = float(np.median(period[known])) if known.any() else 0.0
    took = np.where(data.has_burst, count * np.where(np.isfinite(period), period, typical), 0.0)
    offsets: np.ndarray = np.zeros_like(span)
    start = data.burst_start_s
    for j in range(1, offsets.shape[1]):
        chained = (data.has_burst[:, j] & data.has_burst[:, j - 1]
                   & (start[:, j] == start[:, j - 1]))
        offsets[:, j] = np.where(chained, offsets[:, j - 1] + took[:, j - 1], 0.0)
    return offsets


def command_s(data: RecordArrays) -> np.ndarray:
    """When each move's command could leave, s: its start plus the bursts read before it.

    ``start_s`` is the end of the previous wait; a burst read after that wait delays the
    command by its span (docs/records.md), and by the bursts read before it without a wait
    between (:func:`chained_offsets_s`).
    """
    span = np.nan_to_num(data.burst_span_s) + chained_offsets_s(data)
    result: np.ndarray = data.start_s + _slot_before(span)
    return result


def _slot_before(values: np.ndarray) -> np.ndarray:
    """(T, M) each slot's value of the slot before it in its trial (0 or False for the first)."""
    result: np.ndarray = np.concatenate([np.zeros_like(values[:, :1]), values[:, :-1]], axis=1)
    return result


def timed_moves(data: RecordArrays) -> tuple[np.ndarray, np.ndarray]:
    """(distance mm, command-to-in-position s as recorded) of every move with a previous target."""
    use = data.valid & np.isfinite(data.move_mm) & (data.move_mm > 0)
    took = data.in_position_s - command_s(data)
    use &= took > 0  # a move after a probe's dwell: its start is the dwell's, not the command's
    return data.move_mm[use], took[use]


TICK_SCATTER_S = 0.002
"""Scatter of a recorded time about the continuous model besides the polling (the 4 ms
interpolation grid, half a tick), s: the width of the interval likelihood's edges."""
HOLD_COST = 1.02
"""Holding loose arm parameters at the base values is kept only if the fit's cost rises less
than this factor (else the moves need them: they keep their fitted values, undetermined)."""


def _interval_nll(predicted: np.ndarray, took: np.ndarray, period_s: float) -> np.ndarray:
    """-log likelihood of each recorded time: the model's, plus a latency uniform over the period.

    The latency convolved with the grid's Gaussian scatter: the probability that
    ``took - predicted`` lies in ``[0, period)``, smoothed by ``TICK_SCATTER_S``.
    """
    high = (took - predicted) / TICK_SCATTER_S
    low = (took - predicted - period_s) / TICK_SCATTER_S
    chance = np.maximum(ndtr(high) - ndtr(low), 1e-300)
    result: np.ndarray = -np.log(chance)
    return result


def _fit_free(distance: np.ndarray, took: np.ndarray, values: dict[str, float],
              free: list[str], band_mm: float, period_s: float
              ) -> tuple[dict[str, float], dict[str, float], float, float]:
    """Fit ``free`` (the rest at ``values``): fitted values, 1-sigma, RMS (s), cost.

    Least squares on the mean (latency ``period_s / 2``); with a period, the values
    then from the interval likelihood (:func:`_interval_nll`), whose edges pin the
    recorded times' model tighter than the latency's scatter. The uncertainties are
    least squares' with the polling's worst case (:func:`latency_bound`): a
    flat-topped likelihood's curvature would claim more than the windows tell apart
    (over the computer link lag, acceleration and delay trade off inside them).
    """
    params = [p for p in ARM if p.name in free]
    low = np.array([p.low for p in params])
    high = np.array([p.high for p in params])
    x0 = np.clip(np.array([values[p.name] for p in params]), low * 1.0001 + 1e-9, high * 0.9999)
    late = 0.5 * period_s

    def arm_of(x: np.ndarray) -> dict[str, float]:
        return {**values, **dict(zip(free, x.tolist(), strict=True))}

    def residuals(x: np.ndarray) -> np.ndarray:
        error: np.ndarray = predict_in_position_s(distance, arm_of(x), band_mm) + late - took
        return error

    result = least_squares(residuals, x0, bounds=(low, high), x_scale="jac", method="trf",
                           max_nfev=200)
    x = result.x
    spread = sigmas(result.jac, result.fun)
    if period_s > 0:
        spread = np.hypot(spread, latency_bound(result.jac, period_s))
    cost = float(result.cost)
    if period_s > 0:
        scale = np.maximum(np.abs(x), 1e-3 * (high - low))

        def nll(u: np.ndarray) -> float:
            predicted = predict_in_position_s(distance, arm_of(u * scale), band_mm)
            return float(np.sum(_interval_nll(predicted, took, period_s)))

        bounds = list(zip((low / scale).tolist(), (high / scale).tolist(), strict=True))
        found = minimize(nll, x / scale, method="L-BFGS-B", bounds=bounds)
        x = np.clip(found.x * scale, low, high)
        cost = float(found.fun)
    fitted = dict(zip(free, x.tolist(), strict=True))
    rms = float(np.sqrt(np.mean(residuals(x) ** 2)))
    return fitted, dict(zip(free, spread.tolist(), strict=True)), rms, cost


def latency_bound(jacobian: np.ndarray, period_s: float) -> np.ndarray:
    """How far each parameter can move while every latency stays within its window, s etc.

    The latency is uniform over the poll period only on average: moves of like
    distances meet the polls at like phases, so their latencies may all sit near
    one end. The least-squares solution moves by ``pinv(J) @ offsets``; with each
    offset anywhere in ``+-period / 2`` the worst case is ``|pinv(J)| @ period / 2``.
    That bound joins the statistical uncertainty (a parameter is determined only
    when the polling cannot hide it).
    """
    result: np.ndarray = np.sum(np.abs(np.linalg.pinv(jacobian)), axis=1) * 0.5 * period_s
    return result


def fit_arm(data: RecordArrays, base: dict[str, float], band_mm: float,
            period_s: float = 0.0) -> ArmFit:
    """Fit the arm's timing; with too few moves keep ``base`` (uncertainty infinite).

    The recorded times are taken as the model's plus a detection latency uniform
    over ``period_s`` (:func:`_fit_free`); the model must explain them within
    ``RMS_LIMIT_S`` and that latency's own scatter (``period_s / sqrt(12)``).
    A parameter the moves do not determine is held at the base value, unless
    holding it raises the cost by more than ``HOLD_COST`` (then it keeps its
    fitted value, still reported as not determined).
    """
    distance, took = timed_moves(data)
    names = [p.name for p in ARM]
    if distance.size < MIN_MOVES:
        return ArmFit({n: base[n] for n in names}, {n: math.inf for n in names}, math.nan,
                      int(distance.size), period_s=period_s)
    free = list(names)
    values = {n: base[n] for n in names}
    spread = {n: math.inf for n in names}
    rms, cost = math.nan, math.inf
    kept: tuple[dict[str, float], dict[str, float], float] | None = None
    for _ in range(3):
        fitted, errors, rms, new_cost = _fit_free(distance, took, values, free, band_mm,
                                                  period_s)
        if kept is not None and new_cost > cost + abs(cost) * (HOLD_COST - 1) + 1.0:
            values, spread, rms = kept  # the moves need them: back to the fit before holding
            break
        cost = new_cost
        values.update(fitted)
        spread = {n: math.inf for n in names}
        spread.update(errors)
        loose = [n for n in free if not BY_NAME[n].determined(values[n], spread[n])]
        if not loose or len(loose) == len(free):
            break
        kept = (dict(values), dict(spread), rms)
        for n in loose:
            if not _at_bound(n, values[n]):  # at a bound the moves say "at least": keep it
                values[n] = base[n]
        free = [n for n in free if n not in loose]
    full, _, _, _ = _fit_free(distance, took, base, names, band_mm, period_s)
    timing = {**base, **full}
    beyond = outside_window_s(predict_in_position_s(distance, timing, band_mm), took,
                              period_s)
    explained = float(np.sqrt(np.mean(beyond**2))) <= RMS_LIMIT_S
    if not explained:
        return ArmFit(
            {n: base[n] for n in names}, {n: math.inf for n in names}, rms,
            int(distance.size),
            f"the timing model leaves the recorded times {np.sqrt(np.mean(beyond**2)) * 1000:.0f}"
            f" ms RMS outside their {period_s * 1000:.0f} ms polling windows (more than "
            f"{RMS_LIMIT_S * 1000:.0f} ms): they hold what it lacks, so no arm parameter is "
            "taken from them; the base values are held", period_s)
    free_sigmas: dict[str, float] = {}
    for n in names:
        if _at_bound(n, values[n]) or not BY_NAME[n].determined(values[n], spread[n]):
            free_sigmas[n] = spread[n]
            values[n], spread[n] = base[n], math.inf  # held at the base value
    note = ""
    if not all(math.isfinite(spread[n]) for n in names):
        note = (f"held at the base config's value: the moves' timing (recorded up to one "
                f"{period_s * 1000:.0f} ms poll late) does not single it out; the other arm "
                "parameters trade off against it inside the polling windows, and the "
                "uncertainty includes the polling's worst case, which more trials of the "
                "same moves do not shrink: a finer poll does (EGM's 4 ms feedback, or a "
                "faster computer link)" if period_s > 0 else
                "held at the base config's value: the moves' timing does not determine it")
    return ArmFit(values, spread, rms, int(distance.size), note, period_s, timing, free_sigmas)


def _at_bound(name: str, value: float) -> bool:
    """True when ``value`` sits on a bound of the arm parameter ``name``."""
    param = BY_NAME[name]
    return min(value - param.low, param.high - value) <= 1e-3 * (param.high - param.low)


def outside_window_s(predicted: np.ndarray, took: np.ndarray, period_s: float) -> np.ndarray:
    """How far (s) each recorded time lies outside ``[predicted, predicted + period_s]``."""
    result: np.ndarray = (np.maximum(0.0, predicted - took)
                          + np.maximum(0.0, took - period_s - predicted))
    return result


GRID_NEEDS = ("accel_mm_s2", "lag_s")
"""Arm parameters the moves must determine for their in-position to be put on the tick grid."""


def after_burst_read(data: RecordArrays) -> np.ndarray:
    """(T, M) bool: each move's command waited for a burst of more than one sample."""
    return _slot_before(data.has_burst & (data.count > 1))


def _mean_in_position_s(data: RecordArrays, command: np.ndarray, timing: dict[str, float],
                        band_mm: float) -> np.ndarray:
    """(T, M) each move's in-position by ``timing``'s mean over the grid's phase, s."""
    result: np.ndarray = command + predict_in_position_s(np.nan_to_num(data.move_mm), timing,
                                                         band_mm)
    return result


def _motion_ticks(data: RecordArrays, timing: dict[str, float], band_mm: float) -> np.ndarray:
    """(T, M) the whole ticks from each move's first tick of motion to in position."""
    found = arm_model.profile(np.nan_to_num(data.move_mm), timing, band_mm)
    return whole_ticks(found.ticks[found.inverse])


def with_grid(arm: ArmFit, data: RecordArrays, band_mm: float, tick_s: float) -> ArmFit:
    """``arm`` with the tick grid ``data``'s timed moves place their in-position on.

    :func:`~forcelearn.tools.twin.tick_grid.fit_grid` over the moves :func:`timed_moves`
    takes, with the arm's timing (:attr:`ArmFit.timing`) for each move's ticks of motion;
    ``arm`` as it is when it has no polling period or no timing, or the windows do not
    determine the grid (:func:`~forcelearn.tools.twin.tick_grid.fit_grid`: it must explain
    97 % of them, and most of those the mean model's times miss), or the moves leave the
    arm's acceleration or lag undetermined (``GRID_NEEDS``): a move's own tick needs its
    own ticks of motion. On the default cell's 300-trial run (44 ms windows, no
    identification) the timing that explains the windows has 28 % more acceleration and
    13 % more lag than the arm; a grid on it explained 96 % of the windows by an offset
    after a burst read of +2.2 ms where the emulator's is -1.7 ms.
    """
    if arm.period_s <= 0 or arm.timing is None or not all(
            math.isfinite(arm.sigmas.get(n, math.inf)) for n in GRID_NEEDS):
        return arm
    command = command_s(data)
    use = (data.valid & np.isfinite(data.move_mm) & (data.move_mm > 0)
           & np.isfinite(data.in_position_s) & (data.in_position_s - command > 0))
    ticks = _motion_ticks(data, arm.timing, band_mm)
    mean = _mean_in_position_s(data, command, arm.timing, band_mm)
    grid = fit_grid(command[use], after_burst_read(data)[use], ticks[use],
                    data.in_position_s[use], arm.period_s, tick_s,
                    arm.timing["start_delay_s"], mean[use])
    return dataclasses.replace(arm, grid=grid)


def true_in_position_s(data: RecordArrays, arm: ArmFit, band_mm: float) -> np.ndarray:
    """When each move was truly in position, as best the records and the arm tell, s.

    The detection saw it within the poll period before the recorded time. Where the
    records place the moves on the controller's tick grid (:attr:`ArmFit.grid`), the
    move's own tick; else, where the arm's timing explains the moves
    (:attr:`ArmFit.timing`), its mean time from the command; else the window's middle
    (the uniform latency's mean). Kept inside the window, never before the command.
    """
    period = arm.period_s
    recorded = data.in_position_s
    if period <= 0:
        return recorded
    if arm.timing is not None:
        command = command_s(data)
        model = (_mean_in_position_s(data, command, arm.timing, band_mm) if arm.grid is None
                 else arm.grid.in_position_s(command, after_burst_read(data),
                                             _motion_ticks(data, arm.timing, band_mm)))
        estimate = np.clip(model, recorded - period, recorded)
    else:
        estimate = recorded - 0.5 * period
    result: np.ndarray = np.where(np.isfinite(data.move_mm) & (data.move_mm > 0),
                                  np.maximum(estimate, data.start_s), recorded)
    return result


def with_true_in_position(data: RecordArrays, arm: ArmFit, band_mm: float) -> RecordArrays:
    """``data`` as it happened: in position before the poll that saw it, bursts after its answer.

    Each move's in-position time moves back by its detection latency
    (:func:`true_in_position_s`); each burst's start moves on by the poll's answer
    time (the wait's end is stamped when the last poll's request arrived; the
    driver asks for samples once its reply is in) and by the bursts read before it
    since that wait (:func:`chained_offsets_s`); a move whose robot reported no
    reached pose ends where the lagging tool entered the band (:func:`reached_in_position_mm`).
    """
    in_position = true_in_position_s(data, arm, band_mm)
    timed = dataclasses.replace(data, in_position_s=in_position)
    begun = data.burst_start_s + arm.answer_s + chained_offsets_s(data)
    return dataclasses.replace(timed, burst_start_s=begun,
                               reached=reached_in_position_mm(timed, arm.values, band_mm))


def reached_in_position_mm(data: RecordArrays, arm: dict[str, float], band_mm: float
                           ) -> np.ndarray:
    """Where the tool was when each move came in position, (T, M, 3) mm.

    A robot that reports no reached pose (the computer link; the records then hold the
    commanded one) was not there: the lagging tool enters the in-position band short of
    the target and goes on toward it with the servo lag (:func:`arm_model.share_at_in_position`
    along the straight move from the previous target; the forward model closes the rest
    with the lag, :func:`~.forward.predict_means`), and the last move's own error is still
    decaying (:func:`_carried_lag_mm`). Taken as at the target, the
    foam model ended every step up to the band (0.1 mm) deeper at in position: on the
    step-and-hold of hidden cell 10 of seed 1, without noise, the first burst after each
    3 mm step read 0.04 N under the model at the truth, and the relaxation ratio that fitted
    best was 21 % low (+3 % with this). A reported pose is kept.
    """
    commanded = data.commanded
    previous = np.concatenate([commanded[:, :1], commanded[:, :-1]], axis=1)
    unreported = np.all(data.reached == commanded, axis=-1) & np.isfinite(data.move_mm)
    lag = arm.get("lag_s", 0.0)
    if not unreported.any() or lag <= 0 or "accel_mm_s2" not in arm:
        return data.reached
    share = arm_model.share_at_in_position(np.where(unreported, data.move_mm, 0.0), arm,
                                           band_mm)
    modelled = previous + share[..., None] * (commanded - previous)
    result: np.ndarray = np.where(unreported[..., None], modelled, data.reached)
    return _carried_lag_mm(result, commanded, data.in_position_s, unreported, lag)


def _carried_lag_mm(reached: np.ndarray, commanded: np.ndarray, in_position_s: np.ndarray,
                    unreported: np.ndarray, lag_s: float) -> np.ndarray:
    """``reached`` (T, M, 3, mm) with each unreported move's share of the last move's error.

    The servo lag is linear: the error the tool had at the last move's in position
    (``reached - commanded``) decays as ``exp(-t / lag)`` whatever the reference does
    next, so at this move's in position it is still there, decayed over the time between
    the two. On a still move (a hold) that is all the move is. With a long lag it sets the
    direction the tool creeps in during a burst after a press: on hidden cell 02 of seed 3
    (lag 0.18 s) the previous move's ~1e-3 of the band along Z turned the creep of three
    presses per trial from a slide up the tilted surface to none, as the emulated sponge
    has it (the roller's friction of 0.2 N on the reading).
    """
    result = reached.copy()
    for j in np.flatnonzero(unreported.any(axis=0)):
        if j == 0:
            continue
        since = np.nan_to_num(in_position_s[:, j] - in_position_s[:, j - 1])
        shrink = np.exp(-np.maximum(since, 0.0) / lag_s)[:, None]
        carried = result[:, j] + (result[:, j - 1] - commanded[:, j - 1]) * shrink
        result[:, j] = np.where(unreported[:, j, None], carried, result[:, j])
    return result


def _emulated_s(params: MotionParams, distance_mm: float) -> float:
    """Command to in position on the emulator's arm for a move of ``distance_mm``, s.

    The mean over commands sent at five phases of the tick.
    """
    tick = params.tick_s
    home = Pose(900.0, 0.0, 0.0, (0.0, 1.0, 0.0, 0.0))
    took = []
    for phase in (0.1, 0.3, 0.5, 0.7, 0.9):
        motion = ArmMotion(params, home)
        begin = (10 + phase) * tick
        motion.command(Pose(900.0, distance_mm, 0.0, home.quaternion), begin)
        t = begin
        while not motion.in_position and t < begin + 60.0:
            t = (math.floor(t / tick + 1e-9) + 1) * tick
            motion.advance_to(t)
        took.append(t - begin)
    return float(np.mean(took))


def emulator_delay_s(arm: dict[str, float], distances_mm: np.ndarray, band_mm: float,
                     tick_s: float) -> float:
    """The emulator's ``start_delay_s`` that gives the fitted timing (>= 0), s.

    Runs the emulator's arm for a few of the recorded distances and moves the
    delay by the mean difference to the continuous model.
    """
    picks = np.quantile(distances_mm, [0.1, 0.5, 0.9]) if distances_mm.size else np.array([5.0])
    params = MotionParams(
        speed_mm_s=arm["default_speed_mm_s"], accel_mm_s2=arm["accel_mm_s2"],
        start_delay_s=arm["start_delay_s"], lag_s=arm["lag_s"], in_position_mm=band_mm,
        tick_s=tick_s,
    )
    emulated = np.array([_emulated_s(params, float(d)) for d in picks])
    model = predict_in_position_s(picks, arm, band_mm)
    return max(0.0, arm["start_delay_s"] - float(np.mean(emulated - model)))
