"""The arm's part of the twin: delay, acceleration, speed and lag from the moves' timing.

Each recorded move gives the time from its command to in position; the model
(:func:`forcelearn.tools.twin.forward.predict_in_position_s`) is fitted by
least squares. The model runs in continuous time, the emulator on its tick
grid, which adds a few ms; :func:`emulator_delay_s` measures that on the
emulator's own :class:`~forcelearn.emulators.physics.arm_motion.ArmMotion`
so the twin's arm reproduces the recorded times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.forward import predict_in_position_s
from forcelearn.tools.twin.params import ARM, BY_NAME
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


def timed_moves(data: RecordArrays) -> tuple[np.ndarray, np.ndarray]:
    """(distance mm, command-to-in-position s) of every move with a previous target."""
    use = data.valid & np.isfinite(data.move_mm) & (data.move_mm > 0)
    return data.move_mm[use], (data.in_position_s - data.start_s)[use]


def fit_arm(data: RecordArrays, base: dict[str, float], band_mm: float) -> ArmFit:
    """Fit the arm's timing; with too few moves keep ``base`` (uncertainty infinite)."""
    distance, took = timed_moves(data)
    names = [p.name for p in ARM]
    if distance.size < MIN_MOVES:
        return ArmFit({n: base[n] for n in names}, {n: math.inf for n in names}, math.nan,
                      int(distance.size))
    free = list(names)
    values = {n: base[n] for n in names}
    spread = {n: math.inf for n in names}
    rms = math.nan
    for _ in range(3):  # parameters the timing does not determine keep the base value
        params = [p for p in ARM if p.name in free]
        low = np.array([p.low for p in params])
        high = np.array([p.high for p in params])
        start = np.clip(np.array([base[p.name] for p in params]), low * 1.0001 + 1e-9,
                        high * 0.9999)

        def residuals(x: np.ndarray, free: list[str] = free) -> np.ndarray:
            arm = {**values, **dict(zip(free, x.tolist(), strict=True))}
            error: np.ndarray = predict_in_position_s(distance, arm, band_mm) - took
            return error

        result = least_squares(residuals, start, bounds=(low, high), x_scale="jac",
                               method="trf", max_nfev=200)
        values.update(zip(free, result.x.tolist(), strict=True))
        spread = {n: math.inf for n in names}
        spread.update(zip(free, sigmas(result.jac, result.fun).tolist(), strict=True))
        rms = float(np.sqrt(np.mean(result.fun**2)))
        loose = [n for n in free if not BY_NAME[n].determined(values[n], spread[n])]
        for n in loose:
            values[n] = base[n]
            spread[n] = math.inf
        free = [n for n in free if n not in loose]
        if not loose or not free:
            break
    if rms > RMS_LIMIT_S:
        return ArmFit(
            {n: base[n] for n in names}, {n: math.inf for n in names}, rms,
            int(distance.size),
            f"the timing model leaves {rms * 1000:.0f} ms RMS (more than "
            f"{RMS_LIMIT_S * 1000:.0f} ms): the recorded times hold what it lacks (the link's "
            "polling), so no arm parameter is taken from them; the base values are kept",
        )
    return ArmFit(values, spread, rms, int(distance.size))


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
