"""The hidden-cell study's honesty checks: the member chosen, the identified values, 3-sigma.

Pure functions over a study's files (``cell-XX.truth.json`` and the twin's ``twin.json``):

* **member**: the true member is the simplest member of the family the fit considered
  that holds every mechanism the cell has (relaxation, a stiffening exponent, hysteresis;
  friction only when the fit considered the friction member: a reading along the surface
  normal barely sees it). The twin's choice counts when it is that member, or a simpler
  one it contains that the records could not tell from it (``twin.json``'s choice notes;
  :mod:`forcelearn.tools.twin.choice`); a richer member claims a mechanism the cell lacks.
* **identified**: the arm's lag and acceleration and the foam's relaxation ratio and time
  against the truth, within ``IDENTIFIED_TOLERANCE`` (and, as a second column, within the
  larger of it and the fit's own absolute determination bound, for values near 0).
* **three sigma**: every parameter the twin reports determined whose truth the cell
  knows, more than ``OFF_SIGMAS`` of its reported 1-sigma from it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.tools.results.twin_compare import load_json
from forcelearn.tools.twin.params import BY_NAME

IDENTIFIED_TOLERANCE = 0.15
"""The identified values must lie within this share of the truth."""
IDENTIFIED = ("lag_s", "accel_mm_s2", "relaxation_ratio", "relaxation_time_s")
OFF_SIGMAS = 3.0
NOT_COMPARED = ("start_delay_s", "default_speed_mm_s")
"""The twin's start delay holds the link's time to send a command (not the emulator's
``start_delay_s``); the robot's own speed is what it was set to, never reached by short moves."""
MECHANISM_OF = (("relaxation_ratio", 0.0, "linear"), ("stiffening_exponent", 1.0, "nonlinear"),
                ("hysteresis_loss", 0.0, "hysteretic"),
                ("friction_coefficient", 0.0, "hysteretic+friction"))
"""Each mechanism's amplitude, its off value, and the first member that fits it."""


def truth_values(truth: dict[str, Any]) -> dict[str, float]:
    """Every parameter a hidden cell's truth gives, by the twin's names (arm defaults filled)."""
    arm = ArmConfig()
    values = {k: float(v) for k, v in truth["sponge"].items()}
    values.update({"lag_s": float(truth["arm"]["lag_s"]),
                   "accel_mm_s2": float(truth["arm"].get("accel_mm_s2", arm.accel_mm_s2)),
                   "noise_std": float(truth["sensor"]["noise_n"])})
    return values


def true_member(truth: dict[str, Any], fitted: Sequence[str]) -> str:
    """The simplest of ``fitted`` (member names, simplest first) holding the cell's mechanisms."""
    values = truth_values(truth)
    needed = [member for name, off, member in MECHANISM_OF
              if values.get(name, off) != off and member in fitted]
    if not needed:
        return fitted[0]
    return max(needed, key=list(fitted).index)


@dataclass(frozen=True)
class MemberCheck:
    """The twin's member against the cell's."""

    cell: str
    chosen: str
    truth: str
    verdict: str
    """``true``, ``cannot tell`` (a simpler member the records could not tell from the
    truth) or ``wrong`` (a richer member, or a simpler one the records could tell)."""


def member_check(cell: str, truth: dict[str, Any], twin: dict[str, Any]) -> MemberCheck:
    """Judge ``twin``'s chosen member against ``truth``."""
    fitted = [m["name"] for m in twin["members"]]
    chosen, actual = str(twin["member"]), true_member(truth, fitted)
    if chosen == actual:
        return MemberCheck(cell, chosen, actual, "true")
    simpler = fitted.index(chosen) < fitted.index(actual)
    told = any("cannot tell" in note and actual in note for note in twin.get("choice", []))
    between = fitted[fitted.index(chosen) + 1: fitted.index(actual) + 1] if simpler else []
    told = told or any("cannot tell" in note and name in note
                       for note in twin.get("choice", []) for name in between)
    return MemberCheck(cell, chosen, actual, "cannot tell" if simpler and told else "wrong")


@dataclass(frozen=True)
class Identified:
    """One identified value against the truth."""

    name: str
    truth: float
    value: float
    sigma: float | None
    determined: bool

    @property
    def relative(self) -> float:
        """(value - truth) / truth (inf for a truth of 0 and another value)."""
        if self.truth == 0:
            return 0.0 if self.value == 0 else math.inf
        return (self.value - self.truth) / self.truth

    @property
    def within(self) -> bool:
        """Within ``IDENTIFIED_TOLERANCE`` of the truth."""
        return abs(self.relative) <= IDENTIFIED_TOLERANCE

    @property
    def within_floor(self) -> bool:
        """Within the tolerance or the fit's absolute determination bound of the truth."""
        bound = BY_NAME[self.name].absolute or 0.0
        return self.within or abs(self.value - self.truth) <= bound


def identified(truth: dict[str, Any], twin: dict[str, Any]) -> list[Identified]:
    """The ``IDENTIFIED`` parameters of ``twin`` against ``truth``."""
    values = truth_values(truth)
    rows = {row["name"]: row for row in twin["parameters"]}
    out = []
    for name in IDENTIFIED:
        row = rows.get(name)
        if row is None:
            continue
        sigma = row.get("sigma")
        out.append(Identified(name, values[name], float(row["value"]),
                              None if sigma is None else float(sigma), bool(row["determined"])))
    return out


@dataclass(frozen=True)
class Deviation:
    """A value the twin reports determined, against the truth, in its reported sigmas."""

    name: str
    value: float
    sigma: float
    truth: float

    @property
    def z(self) -> float:
        """(value - truth) / sigma."""
        return (self.value - self.truth) / self.sigma


def deviations(truth: dict[str, Any], twin: dict[str, Any]) -> list[Deviation]:
    """Every value ``twin`` reports determined with a sigma whose truth the cell knows."""
    values = truth_values(truth)
    out = []
    for row in twin["parameters"]:
        name, sigma = row["name"], row.get("sigma")
        if (not row["determined"] or name in NOT_COMPARED or name not in values
                or sigma is None or not sigma > 0):
            continue
        out.append(Deviation(name, float(row["value"]), float(sigma), values[name]))
    return out


def three_sigma_offs(truth: dict[str, Any], twin: dict[str, Any]) -> list[str]:
    """Parameters reported determined but more than ``OFF_SIGMAS`` sigma from the truth."""
    return [f"{d.name} {d.value:.4g} ± {d.sigma:.2g} vs {d.truth:.4g} ({d.z:+.1f} sigma)"
            for d in deviations(truth, twin) if abs(d.z) > OFF_SIGMAS]


def identification_arm(truth: dict[str, Any], folder: Path) -> list[Identified]:
    """Lag and acceleration from a cell's identification run alone (``folder``), vs truth.

    The values ``forcelearn twin --identification`` takes (:func:`timing_of` its polled
    moves); empty when the folder has none or too few moves.
    """
    from forcelearn.tools.twin.identify import read_identification
    from forcelearn.tools.twin.identify_fit import timing_of

    timing = timing_of(read_identification(folder))
    if timing is None:
        return []
    values = truth_values(truth)
    return [Identified(n, values[n], timing.values[n], timing.sigmas[n],
                       BY_NAME[n].determined(timing.values[n], timing.sigmas[n]))
            for n in ("lag_s", "accel_mm_s2")]


def _count(flags: Sequence[bool]) -> str:
    return f"{sum(flags)}/{len(flags)}"


def page_lines(out: Path, cells: Sequence[str]) -> list[str]:
    """The study page's section on member choice, identified values and 3-sigma offs."""
    members: list[MemberCheck] = []
    found: list[tuple[str, list[Identified]]] = []
    offs: list[str] = []
    missing: list[str] = []
    for cell in cells:
        twin_json = out / cell / "twin" / "twin.json"
        if not twin_json.exists():
            missing.append(cell)
            continue
        truth = load_json(out / "cells" / f"{cell}.truth.json")
        twin = load_json(twin_json)
        members.append(member_check(cell, truth, twin))
        found.append((cell, identified(truth, twin)))
        offs.extend(f"{cell}: {text}" for text in three_sigma_offs(truth, twin))
    lines = ["## Member chosen, identified values, parameters 3 sigma off", ""]
    if missing:
        lines += [f"No twin.json (not fitted yet, or the fit failed): {', '.join(missing)}.", ""]
    ok = [m.verdict != "wrong" for m in members]
    lines += [f"- Member: the true one or one the records cannot tell from it on "
              f"{_count(ok)} cells (exactly the true one on "
              f"{_count([m.verdict == 'true' for m in members])}).", ""]
    for name in IDENTIFIED:
        rows = [i for _, values in found for i in values if i.name == name]
        share = f"{IDENTIFIED_TOLERANCE:.0%}"
        floor = BY_NAME[name].absolute or 0.0
        lacking = len(found) - len(rows)  # the chosen member does not fit it: not identified
        pad = [False] * lacking
        lines.append(f"- {name}: within {share} on {_count([i.within for i in rows] + pad)} "
                     f"cells; within {share} or {floor:g} on "
                     f"{_count([i.within_floor for i in rows] + pad)}; reported determined on "
                     f"{_count([i.determined for i in rows] + pad)}"
                     + (f" (on {lacking} the chosen member does not fit it)" if lacking else ""))
    lines += ["", f"- Parameters reported determined more than {OFF_SIGMAS:g} sigma from the "
              f"truth: {len(offs)}" + (":" if offs else "."), *[f"  - {o}" for o in offs], ""]
    arm_rows: list[tuple[str, list[Identified]]] = []
    for cell in cells:
        if (out / cell / "identify.done").exists() and (out / cell / "identify").is_dir():
            truth = load_json(out / "cells" / f"{cell}.truth.json")
            arm_rows.append((cell, identification_arm(truth, out / cell / "identify")))
    lines += [f"- From the identification runs alone ({len(arm_rows)} cells; the arm the twin "
              "takes from them):"]
    for name in ("lag_s", "accel_mm_s2"):
        rows = [i for _, values in arm_rows for i in values if i.name == name]
        share = f"{IDENTIFIED_TOLERANCE:.0%}"
        lines.append(f"  - {name}: within {share} on {_count([i.within for i in rows])}; "
                     f"reported determined on {_count([i.determined for i in rows])}; "
                     + ", ".join(f"{c} {i.value:.4g} vs {i.truth:.4g} ({i.relative:+.0%})"
                                 for c, values in arm_rows for i in values if i.name == name))
    lines += ["", "| cell | true member | chosen | verdict | " + " | ".join(IDENTIFIED) + " |",
              "|---|---|---|---|" + "---|" * len(IDENTIFIED)]
    for check, (_, values) in zip(members, found, strict=True):
        by = {i.name: i for i in values}
        cells_text = [f"{by[n].value:.4g} vs {by[n].truth:.4g} ({by[n].relative:+.0%})"
                      + ("" if by[n].determined else " (undet.)") if n in by else "-"
                      for n in IDENTIFIED]
        lines.append(f"| {check.cell} | {check.truth} | {check.chosen} | {check.verdict} | "
                     + " | ".join(cells_text) + " |")
    return [*lines, ""]
