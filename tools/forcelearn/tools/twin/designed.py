"""An identification plan designed from a twin's uncertainties: run what the records lack.

``forcelearn identify --design TWIN_JSON`` reads a twin's report (``forcelearn twin``'s
``twin.json``) and keeps only the parts of the identification (:mod:`.identify`) that
determine what the twin left undetermined, each sized so that its expected 1-sigma is at
most ``TARGET_SHARE`` of the value (a 15 % error then three sigma off):

=============================  ============================================  ==============
undetermined (or not fitted)   part kept                                     sized by
=============================  ============================================  ==============
lag, acceleration, start       polled free-space moves of each length x      passes over
delay                          speed                                         them
relaxation ratio or time (or   step-and-hold, held to 6 time constants of    holds
a member without relaxation)   the twin's relaxation time (1 s: unknown),
                               and the cycles' short holds (each step in
                               and out a relaxation of its own)
hysteresis (a member with it   ease off and press in again                   cycles
undetermined)
noise, drift                   free-space hold                               its reads
=============================  ============================================  ==============

The expected 1-sigma is the Fisher information's (Gauss-Newton ``(J^T J)^-1``) at the
twin's values: for the arm the twin's own in-position model
(:func:`~forcelearn.tools.twin.forward.predict_in_position_s`) over the plan's moves, each
event timed to a poll window's ``width / sqrt(12)``, and with the plan's pose reads the
tool's progress read every ``READ_PERIOD_S`` of each move, to the controller's tick at the
path's speed (:func:`arm_sigmas`: one pass then puts the acceleration within 1 %, where the
windows alone left 12 %); for the relaxation a relaxing step
``F(t) = F_inf + A exp(-(delay + t) / tau)`` per hold, each burst's mean with the noise
over its samples, the first burst ``delay`` after the step's middle (half the arm's motion
and the settle: what relaxed during the move is not seen); for the noise ``1 / sqrt(2 n)``.
A designed plan's figures are the fit's best case: model error (that the records show as
a misfit) comes on top.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.tools.twin.arm_model import TICK_S, progress_mm
from forcelearn.tools.twin.forward import predict_in_position_s
from forcelearn.tools.twin.identify import IdentifyPlan
from forcelearn.tools.twin.identify_fit import READ_FLOOR_MM

TARGET_SHARE = 0.05
"""The designed 1-sigma, as a share of the value (a 15 % error is then 3 sigma)."""
POLL_S = 0.044
"""The status poll's period on a 9600-baud computer link, s (EGM's 4 ms is finer)."""
READ_PERIOD_S = 0.127
"""A status poll and the pose read after it on that link, s (the in-position window)."""
SAMPLE_S = 0.001
"""A force sample's period, s (the emulated JR3 adapter's 1 kHz)."""
BAND_MM = 0.1
"""The in-position band, mm (the controller's default)."""
ARM_NAMES = ("start_delay_s", "accel_mm_s2", "lag_s")
RELAXATION = ("relaxation_ratio", "relaxation_time_s")
HYSTERESIS = ("hysteresis_loss", "hysteresis_depth_mm")
SENSOR = ("noise_std", "bias_drift_per_sqrt_s")
MAX_REPEATS = 4
MAX_HOLDS = 10
UNKNOWN_TIME_S = 1.0
"""The relaxation time assumed when the twin has none (the slowest foam the study draws)."""
HOLD_TIMES = 6.0
"""Holds last this many relaxation time constants."""


@dataclass(frozen=True)
class Design:
    """A designed plan, why each part is in it, and the 1-sigma it expects by parameter."""

    plan: IdentifyPlan
    reasons: list[str]
    expected: dict[str, tuple[float, float]]
    """Parameter -> (the twin's value, the 1-sigma the plan is expected to leave)."""

    def document(self) -> dict[str, Any]:
        """JSON-able: the plan, its cell time, why, and the expected uncertainties."""
        return {"plan": dataclasses.asdict(self.plan),
                "cell_time_s": round(self.plan.cell_time_s(), 1), "why": self.reasons,
                "expected": {n: {"value": v, "sigma": s, "share": s / abs(v) if v else None}
                             for n, (v, s) in self.expected.items()}}


def _rows(twin: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {row["name"]: row for row in twin["parameters"]}


def _loose(rows: dict[str, dict[str, Any]], names: tuple[str, ...]) -> list[str]:
    """Of ``names``, those the twin does not report determined (or does not fit at all)."""
    return [n for n in names if n not in rows or not rows[n].get("determined")]


def _known(rows: dict[str, dict[str, Any]], name: str, otherwise: float) -> float:
    """The twin's value of ``name`` if known to half its size, else ``otherwise``."""
    row = rows.get(name)
    if row is None or row.get("value") is None:
        return otherwise
    value, sigma = float(row["value"]), row.get("sigma")
    known = sigma is not None and math.isfinite(float(sigma)) and float(sigma) < 0.5 * value
    return value if known and value > 0 else otherwise


def arm_sigmas(arm: dict[str, float], plan: IdentifyPlan, poll_s: float = POLL_S
               ) -> dict[str, float]:
    """Expected 1-sigma of ``ARM_NAMES`` from the plan's polled moves (Fisher information).

    Each move's in-position event in a window of ``poll_s`` (``READ_PERIOD_S`` with the
    plan's pose reads); with them, the tool's progress read every ``READ_PERIOD_S`` from
    the command (at the middle of the period, the read's offset a fourth unknown) to one
    period after in position, scattered by the tick at the path's speed.
    """
    lengths = np.array([length for _ in range(plan.repeats) for _ in plan.speeds_mm_s
                        for length in plan.lengths_mm for _ in range(2)])
    speeds = np.array([speed for _ in range(plan.repeats) for speed in plan.speeds_mm_s
                       for _ in plan.lengths_mm for _ in range(2)])
    names = 4 if plan.read_positions else 3  # the reads' offset after the timing
    base = np.array([*(arm[n] for n in ARM_NAMES), READ_PERIOD_S / 3][:names])
    window = READ_PERIOD_S if plan.read_positions else poll_s
    done = predict_in_position_s(lengths, arm, BAND_MM, speeds)
    per_move = np.ceil(done / READ_PERIOD_S).astype(int) + 1
    read_move = np.repeat(np.arange(lengths.size), per_move)
    read_at = (np.concatenate([np.arange(n) for n in per_move]) + 0.5) * READ_PERIOD_S

    def model(x: np.ndarray) -> np.ndarray:
        p = {**arm, **dict(zip(ARM_NAMES, x[:3].tolist(), strict=True))}
        result: np.ndarray = predict_in_position_s(lengths, p, BAND_MM, speeds) / window
        if plan.read_positions:
            path = progress_mm(lengths[read_move], p, BAND_MM, read_at + x[3] - x[0],
                               speeds[read_move])
            result = np.concatenate([result, path / read_scatter])
        return result

    read_scatter = 1.0
    if plan.read_positions:
        ahead = progress_mm(lengths[read_move], arm, BAND_MM,
                            read_at + base[3] - base[0] + TICK_S, speeds[read_move])
        read_scatter = np.hypot((ahead - progress_mm(lengths[read_move], arm, BAND_MM,
                                                     read_at + base[3] - base[0],
                                                     speeds[read_move])) / math.sqrt(12),
                                READ_FLOOR_MM)
    steps = np.maximum(np.abs(base) * 1e-3, 1e-6)
    jacobian = np.stack([(model(base + np.eye(names)[i] * steps[i])
                          - model(base - np.eye(names)[i] * steps[i])) / (2 * steps[i])
                         for i in range(names)], axis=1)
    jacobian[:lengths.size] /= math.sqrt(1 / 12 + (TICK_S / window) ** 2 / 12)
    return dict(zip(ARM_NAMES, _fisher_sigmas(jacobian, 1.0)[:3].tolist(), strict=True))


def _read_times(after: tuple[float, ...], poll_s: float, burst_s: float) -> list[float]:
    """When a hold's bursts are read (s after its first): each wait at least a poll and a burst."""
    times = [0.0]
    for t in after:
        times.append(max(t, times[-1] + poll_s + burst_s))
    return times


def relaxation_sigmas(ratio: float, time_s: float, step_n: float, noise_n: float,
                      plan: IdentifyPlan, poll_s: float = POLL_S, delay_s: float = 0.0,
                      sample_s: float = SAMPLE_S) -> dict[str, float]:
    """Expected 1-sigma of the relaxation's ratio and time from the plan's holds.

    Each hold (the step-and-hold's ``hold_steps``, and each of the cycles' steps in and out,
    read at ``cycle_hold_s``): ``F_inf + A exp(-(delay + t) / tau)`` with ``A = ratio /
    (1 + ratio) * step_n`` (a step that meets ``step_n`` at once relaxes to ``step_n / (1 +
    ratio)``), its own ``F_inf``; its first burst ``delay_s`` after the step (the move's
    time to in position: the relaxation that happened during it is not seen), then one at
    each time of its schedule (each wait at least a poll and a burst).
    """
    burst_s = plan.hold_samples * sample_s
    schedules = [np.array(_read_times(plan.hold_s, poll_s, burst_s))] * max(1, plan.hold_steps)
    if plan.hold_steps >= 2 and plan.cycle_hold_s:
        schedules += ([np.array(_read_times(plan.cycle_hold_s, poll_s, burst_s))]
                      * (plan.cycles * 2 * (plan.hold_steps - 1)))
    size = max(ratio, 1e-3) / (1 + max(ratio, 1e-3)) * step_n
    rows = sum(t.size for t in schedules)
    columns = np.zeros((rows, 2 + len(schedules)))
    start = 0
    for k, t in enumerate(schedules):
        seen = t + delay_s
        decay = np.exp(-seen / time_s)
        part = slice(start, start + t.size)
        columns[part, 0] = decay  # dF/dA
        columns[part, 1] = size * seen / time_s**2 * decay  # dF/dtau
        columns[part, 2 + k] = 1.0  # each hold's own relaxed force
        start += t.size
    sigma_a, sigma_tau = _fisher_sigmas(columns, noise_n / math.sqrt(plan.hold_samples))[:2]
    # ratio = A / (step_n - A): d ratio / dA = step_n / (step_n - A)^2
    sigma_ratio = sigma_a * step_n / max(step_n - size, 1e-9) ** 2
    return {"relaxation_ratio": float(sigma_ratio), "relaxation_time_s": float(sigma_tau)}


def step_delay_s(arm: dict[str, float], plan: IdentifyPlan, poll_s: float = POLL_S) -> float:
    """From a step's depth change (its motion's middle) to its first burst, s.

    Half the arm's modelled motion of a ``cycle_mm`` step (start delay excluded) and the
    settle of two polls before the burst.
    """
    motion = float(predict_in_position_s(np.array([plan.cycle_mm]), arm, BAND_MM)[0]
                   - arm["start_delay_s"])
    return 0.5 * max(motion, 0.0) + 2 * poll_s


def _fisher_sigmas(jacobian: np.ndarray, scatter: float) -> np.ndarray:
    """``scatter * sqrt(diag((J^T J)^-1))`` (inf where J does not see a direction)."""
    information = jacobian.T @ jacobian
    try:
        covariance = np.linalg.inv(information)
    except np.linalg.LinAlgError:
        return np.full(jacobian.shape[1], math.inf)
    result: np.ndarray = scatter * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    return result


def design(twin: dict[str, Any], desired_force_n: float) -> Design:
    """The plan for what ``twin`` (a ``twin.json``) leaves undetermined; see the module."""
    rows = _rows(twin)
    value = {n: float(r["value"]) for n, r in rows.items() if r.get("value") is not None}
    reasons: list[str] = []
    expected: dict[str, tuple[float, float]] = {}
    noise = value.get("noise_std", 0.2)
    base = IdentifyPlan()
    plan = dataclasses.replace(base, lengths_mm=(base.lengths_mm[0],),
                               speeds_mm_s=(base.speeds_mm_s[0],), free_reads=2,
                               free_hold_s=1.0, hold_steps=0, cycles=0)
    arm_loose = _loose(rows, ARM_NAMES)
    arm = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
           "lag_s": 0.03, **{n: value[n] for n in ARM_NAMES if n in value}}
    if arm_loose:
        for repeats in range(1, MAX_REPEATS + 1):
            plan = dataclasses.replace(plan, lengths_mm=base.lengths_mm,
                                       speeds_mm_s=base.speeds_mm_s, repeats=repeats)
            sigmas = arm_sigmas(arm, plan)
            if all(sigmas[n] <= TARGET_SHARE * abs(arm[n]) for n in arm_loose):
                break
        expected.update({n: (arm[n], sigmas[n]) for n in ARM_NAMES})
        reasons.append(f"{', '.join(arm_loose)} not determined: polled moves, "
                       f"{plan.repeats} pass(es) over {len(plan.lengths_mm)} lengths x "
                       f"{len(plan.speeds_mm_s)} speeds")
    relax_loose = _loose(rows, RELAXATION)
    if relax_loose:
        ratio = value.get("relaxation_ratio", 0.25) or 0.25
        time_s = _known(rows, "relaxation_time_s", UNKNOWN_TIME_S)
        longest = HOLD_TIMES * time_s
        hold_s = (*(t for t in base.hold_s if t < longest), longest)
        step_n = base.hold_force_ratio * desired_force_n * (1 + ratio)
        delay = step_delay_s(arm, base)
        for holds in range(2, MAX_HOLDS + 1):
            # the cycles' steps are holds too (short ones: a fast foam's whole relaxation)
            plan = dataclasses.replace(plan, hold_s=hold_s, hold_steps=holds,
                                       cycles=base.cycles)
            sigmas = relaxation_sigmas(ratio, time_s, step_n, noise, plan, delay_s=delay)
            if (sigmas["relaxation_ratio"] <= TARGET_SHARE * ratio
                    and sigmas["relaxation_time_s"] <= TARGET_SHARE * time_s):
                break
        expected.update({"relaxation_ratio": (ratio, sigmas["relaxation_ratio"]),
                         "relaxation_time_s": (time_s, sigmas["relaxation_time_s"])})
        reasons.append(f"{', '.join(relax_loose)} not determined (member {twin['member']}): "
                       f"step-and-hold, {plan.hold_steps} holds of {longest:.2g} s and "
                       f"{plan.cycles} cycles of short holds easing off and pressing in "
                       f"(6 time constants of {time_s:.2g} s"
                       + (", the slowest foam expected: the twin has no time)"
                          if time_s == UNKNOWN_TIME_S else ", the twin's time)"))
    if "hysteresis_loss" in rows and _loose(rows, HYSTERESIS):
        plan = dataclasses.replace(plan, cycles=base.cycles,
                                   hold_steps=max(plan.hold_steps, 2))
        reasons.append(f"hysteresis not determined: {plan.cycles} cycles of easing off "
                       "and pressing in")
    sensor_loose = _loose(rows, SENSOR)
    if sensor_loose:
        plan = dataclasses.replace(plan, free_reads=base.free_reads,
                                   free_hold_s=base.free_hold_s)
        samples = plan.free_reads * plan.free_samples
        expected["noise_std"] = (noise, noise / math.sqrt(2 * samples))
        reasons.append(f"{', '.join(sensor_loose)} not determined: a free-space hold of "
                       f"{plan.free_hold_s:g} s")
    if not reasons:
        reasons.append("the twin determines every parameter this plan could: a minimal "
                       "plan (one move, one press) checks the cell is the twin's")
    return Design(plan, reasons, expected)


def design_from_file(path: Path, desired_force_n: float) -> Design:
    """:func:`design` of a ``twin.json`` file (or of the folder holding it)."""
    file = path / "twin.json" if path.is_dir() else path
    return design(json.loads(file.read_text(encoding="utf-8")), desired_force_n)
