"""The arm from an identification run's polled moves: start delay, acceleration, speed, lag.

Each polled move (:class:`~forcelearn.tools.twin.identify.TimedMove`) brackets its
in-position event between two successive polls (the first poll in position after the
motion). The polls are timed from the command, so moves of many distinct durations meet
them at spread phases: an event is taken as uniform within its window, its middle
unbiased with the window's width / sqrt(12) as its scatter, for a first least-squares fit; the
values then maximise the interval likelihood (the event within its window, the model's
grid scatter smoothing the edges), whose many distinct windows pin the model tighter
than any one window. The 1-sigma stays the least squares' (conservative). (The motion's start is not
used: the first poll after a command always comes one command exchange and one poll
later, long after the start, whatever the dwell before it.) The start delay counts from
the poll before the command, the link's time to send it included, as a run's records
time it. The model is the twin's own
(:func:`~forcelearn.tools.twin.forward.predict_in_position_s`): start delay + trapezoidal
path at the move's speed + the first-order lag's remaining error decaying into the
in-position band. A set speed ``v`` runs at ``speed_scale * v``; the robot's own speed
(the run's) is its own parameter. Least squares over the windows' middles, 1-sigma
cluster-robust by move (:func:`~forcelearn.tools.twin.uncertainty.sigmas`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize
from scipy.special import ndtr

from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.tools.twin.arm import TICK_SCATTER_S, ArmFit
from forcelearn.tools.twin.forward import predict_in_position_s
from forcelearn.tools.twin.identify import Identification, TimedMove
from forcelearn.tools.twin.uncertainty import sigmas

TICK_S = 0.004
BAND_MM = ArmConfig().in_position_mm
"""The in-position band (mm) the twin fits with (the controller's default): the fit
``forcelearn identify`` keeps in its file is for this band."""
"""The controller's interpolation tick, s: added to each window's scatter."""
NAMES = ("start_delay_s", "accel_mm_s2", "default_speed_mm_s", "lag_s")
BOUNDS = {"start_delay_s": (0.0, 1.0), "accel_mm_s2": (10.0, 20000.0),
          "default_speed_mm_s": (1.0, 1000.0), "lag_s": (0.0005, 1.0), "speed_scale": (0.2, 5.0)}
START = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
         "lag_s": 0.03, "speed_scale": 1.0}


@dataclass(frozen=True)
class TimingFit:
    """The arm's timing from polled moves: values and 1-sigma by name, residual RMS (s)."""

    values: dict[str, float]
    sigmas: dict[str, float]
    rms_s: float
    moves: int


@dataclass(frozen=True)
class _Events:
    """Per polled event: its move, kind (0 start, 1 in position), window middle and scatter."""

    move: np.ndarray
    kind: np.ndarray
    middle_s: np.ndarray
    spread_s: np.ndarray
    width_s: np.ndarray


def _events(moves: list[TimedMove]) -> _Events:
    rows: list[tuple[int, int, float, float]] = []
    for i, move in enumerate(moves):
        before = move.command_s
        left_position = False
        for time_s, moving, in_position in move.polls:
            left_position = left_position or moving is True or not in_position
            if left_position and in_position and moving is not True:
                rows.append((i, 1, 0.5 * (before + time_s) - move.command_s, time_s - before))
                break
            before = time_s
    table = np.array(rows, dtype=float).reshape(-1, 4)
    return _Events(table[:, 0].astype(int), table[:, 1].astype(int), table[:, 2],
                   np.sqrt(table[:, 3] ** 2 / 12 + TICK_S**2 / 12), table[:, 3])


def fit_timing(moves: list[TimedMove], band_mm: float = BAND_MM) -> TimingFit | None:
    """Fit the arm's timing to polled moves (None when too few events to fit four values)."""
    if not moves:
        return None
    events = _events(moves)
    if events.middle_s.size < 8:
        return None
    length = np.array([m.length_mm for m in moves])[events.move]
    speed = np.array([m.speed_mm_s for m in moves])[events.move]
    own = np.isnan(speed)
    names = [*NAMES, "speed_scale"] if (~own).any() else list(NAMES)
    if not own.any():
        names.remove("default_speed_mm_s")

    def model(x: np.ndarray) -> np.ndarray:
        p = dict(zip(names, x.tolist(), strict=True))
        # every move at its own speed, all (length, speed) pairs in one tick-grid pass
        own_speed = p.get("default_speed_mm_s", math.nan)
        v = np.where(own, own_speed, p.get("speed_scale", 1.0) * speed)
        total = predict_in_position_s(length, p, band_mm, v)
        result: np.ndarray = np.where(events.kind == 0, p["start_delay_s"], total)
        return result

    def residuals(x: np.ndarray) -> np.ndarray:
        error: np.ndarray = (model(x) - events.middle_s) / events.spread_s
        return error

    low = np.array([BOUNDS[n][0] for n in names])
    high = np.array([BOUNDS[n][1] for n in names])
    x0 = np.clip([START[n] for n in names], low, high)
    result = least_squares(residuals, x0, bounds=(low, high), x_scale="jac")
    one_sigma = sigmas(result.jac, result.fun, events.move)
    scale = np.maximum(np.abs(result.x), 1e-6)
    lower = events.middle_s - 0.5 * events.width_s

    def nll(u: np.ndarray) -> float:
        # the event within its window, the model's grid scatter smoothing the edges
        offset = lower - model(u * scale)
        chance = ndtr((offset + events.width_s) / TICK_SCATTER_S) - ndtr(offset / TICK_SCATTER_S)
        return float(-np.sum(np.log(np.maximum(chance, 1e-300))))

    found = minimize(nll, np.ones(len(names)), method="L-BFGS-B",
                     bounds=list(zip((low / scale).tolist(), (high / scale).tolist(),
                                     strict=True)))
    x = np.clip(found.x * scale, low, high)
    values = dict(zip(names, x.tolist(), strict=True))
    spread = dict(zip(names, one_sigma.tolist(), strict=True))
    rms = float(np.sqrt(np.mean((model(x) - events.middle_s) ** 2)))
    if "default_speed_mm_s" not in values:
        values["default_speed_mm_s"], spread["default_speed_mm_s"] = math.nan, math.inf
    return TimingFit(values, spread, rms, len(moves))


def timing_document(timing: TimingFit, band_mm: float) -> dict[str, object]:
    """``timing`` as ``identification.json`` keeps it (:attr:`Identification.timing`)."""
    return {"band_mm": band_mm, "values": timing.values, "sigmas": timing.sigmas,
            "rms_s": timing.rms_s, "moves": timing.moves}


def timing_of(identification: Identification, band_mm: float = BAND_MM) -> TimingFit | None:
    """The arm's timing from the identification's polled moves (None: too few to fit).

    Read from the file when ``forcelearn identify`` kept its fit for this in-position band
    and these moves (the fit is seconds of CPU; a study reads it three times), else fitted.
    """
    kept = identification.timing
    if (kept is not None and kept.get("band_mm") == band_mm
            and kept.get("moves") == len(identification.moves)):
        return TimingFit({k: float(v) for k, v in kept["values"].items()},
                         {k: float(v) for k, v in kept["sigmas"].items()},
                         float(kept["rms_s"]), int(kept["moves"]))
    return fit_timing(identification.moves, band_mm)


def identified_arm(arm: ArmFit, identification: Identification, band_mm: float) -> ArmFit:
    """``arm`` (the run's) with the timing of an identification's polled moves, when it fits."""
    timing = timing_of(identification, band_mm)
    if timing is None:
        return dataclasses.replace(arm, note=(arm.note + "; " if arm.note else "")
                                   + "the identification has too few polled moves")
    taken = [n for n in arm.values if n in timing.values and math.isfinite(timing.values[n])
             and math.isfinite(timing.sigmas[n])]  # a value the moves leave loose: the run's
    values = {**arm.values, **{n: timing.values[n] for n in taken}}
    spread = {**arm.sigmas, **{n: timing.sigmas[n] for n in taken}}
    return dataclasses.replace(
        arm, values=values, sigmas=spread, rms_s=timing.rms_s, moves=timing.moves,
        note=f"from the identification's {timing.moves} polled moves "
             f"(timing RMS {timing.rms_s * 1000:.1f} ms)")
