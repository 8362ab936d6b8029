"""The fault campaign's reports and table (docs/fuzzing.md, "Faults in contact")."""

from __future__ import annotations

import dataclasses
from collections import Counter, defaultdict
from collections.abc import Sequence


@dataclasses.dataclass
class RunReport:
    """What one run of the campaign found."""

    cell: str
    seed: int
    fired: Counter[tuple[str, str]] = dataclasses.field(default_factory=Counter)
    resumed_from: Counter[str] = dataclasses.field(default_factory=Counter)
    typed_ends: Counter[str] = dataclasses.field(default_factory=Counter)
    untyped_ends: int = 0
    over_limit: int = 0
    max_contact_n: float = 0.0
    zeros: int = 0
    zeros_in_contact: int = 0
    readings: int = 0
    """Readings the run used (booked with a kept trial or probe)."""
    bad_readings: Counter[str] = dataclasses.field(default_factory=Counter)
    voided: int = 0
    """Readings of rolled-back trials (never used)."""
    voided_bad: Counter[str] = dataclasses.field(default_factory=Counter)
    voids: int = 0
    """Trials the zero check voided."""
    worst_used_n: float = 0.0
    """The largest error of a used reading, N."""
    sigma_n: float = float("inf")
    """The sensor's noise sigma, N (the filter's R)."""
    beyond_3sigma: int = 0
    """Used readings more than 3 sigma from the true force."""
    late_stops: int = 0
    worst_stop_s: float = 0.0
    """Robot faults: cell time to the stop, s."""
    worst_read_stop_s: float = 0.0
    """Sensor faults: wall time from the first read after the fault to the stop, s."""
    worst_unread_s: float = 0.0
    """Sensor faults: cell time from the fault to the next read (moves under way), s."""
    lost_or_duplicated: int = 0
    finished: bool = False
    sessions: int = 0
    wall_s: float = 0.0
    problems: list[str] = dataclasses.field(default_factory=list)


def table(reports: Sequence[RunReport]) -> str:
    """The Markdown table of docs/fuzzing.md, one row per device kind (and the run's kills)."""
    by_kind: dict[str, Counter[str]] = defaultdict(Counter)
    runs: dict[str, set[tuple[str, int]]] = defaultdict(set)
    resumed: dict[str, Counter[str]] = defaultdict(Counter)
    for report in reports:
        for (kind, fault), count in report.fired.items():
            by_kind[kind][fault] += count
            runs[kind].add((report.cell, report.seed))
        for key, count in report.resumed_from.items():
            kind, fault = key.split(":")
            resumed[kind][fault] += count
    lines = ["| device kind | runs | faults injected (by kind) | resumed from (by kind) |",
             "|---|---|---|---|"]
    for kind in ("computer_link", "egm", "jr3", "netft", "run"):
        if kind not in by_kind:
            continue
        faults = by_kind[kind]
        lines.append(
            f"| {kind} | {len(runs[kind])} | {sum(faults.values())} ("
            + ", ".join(f"{f} {n}" for f, n in sorted(faults.items())) + ") | "
            + ", ".join(f"{f} {resumed[kind][f]}" for f in sorted(faults)) + " |"
        )
    totals = Counter[str]()
    for report in reports:
        totals["over_limit"] += report.over_limit
        totals["zeros_in_contact"] += report.zeros_in_contact
        totals["zeros"] += report.zeros
        totals["readings"] += report.readings
        totals["beyond_3sigma"] += getattr(report, "beyond_3sigma", 0)
        totals["bad_readings"] += sum(report.bad_readings.values())
        totals["voided"] += report.voided
        totals["voided_bad"] += sum(report.voided_bad.values())
        totals["voids"] += report.voids
        totals["late_stops"] += report.late_stops
        totals["records"] += report.lost_or_duplicated
        totals["untyped"] += report.untyped_ends
        totals["unfinished"] += not report.finished
    bad = Counter[str]()
    for report in reports:
        bad.update(report.bad_readings)
    worst = max((r.max_contact_n for r in reports), default=0.0)
    slowest = max((r.worst_stop_s for r in reports), default=0.0)
    read_stop = max((r.worst_read_stop_s for r in reports), default=0.0)
    unread = max((r.worst_unread_s for r in reports), default=0.0)
    worst_used = max((getattr(r, "worst_used_n", 0.0) for r in reports), default=0.0)
    lines += [
        "",
        f"runs {len(reports)}; true contact force over the limit: {totals['over_limit']} "
        f"(max {worst:.1f} N); zeros in contact: {totals['zeros_in_contact']} of "
        f"{totals['zeros']}; used readings off the true force: {totals['bad_readings']} of "
        f"{totals['readings']} (after: {dict(bad)}; the largest error of a used reading "
        f"{worst_used:.2f} N); used readings beyond 3 sigma of the true force: "
        f"{totals['beyond_3sigma']} (worst by sensor: {worst_sigmas(reports)}); "
        f"voided readings: {totals['voided']} "
        f"({totals['voided_bad']} of them off), trials voided by the zero check: "
        f"{totals['voids']}; stops later than the watchdog: "
        f"{totals['late_stops']} (robot faults: slowest {slowest:.2f} s of cell time; sensor "
        f"faults: slowest {read_stop:.2f} s of wall time from the next read, which came up to "
        f"{unread:.2f} s of cell time after the fault); lost or duplicated "
        f"records: {totals['records']}; "
        f"ends without a typed reason: {totals['untyped']}; runs not finished: "
        f"{totals['unfinished']}",
    ]
    return "\n".join(lines)


def worst_sigmas(reports: Sequence[RunReport]) -> str:
    """The largest error of a used reading per sensor kind, N and in its noise sigma."""
    worst: dict[str, tuple[float, float]] = {}
    for report in reports:
        sensor, sigma = report.cell.split("+")[1], getattr(report, "sigma_n", float("inf"))
        if report.worst_used_n > worst.get(sensor, (0.0, sigma))[0]:
            worst[sensor] = (report.worst_used_n, sigma)
    return ", ".join(f"{s} {n:.2f} N = {n / sigma:.1f} sigma"
                     for s, (n, sigma) in sorted(worst.items()))
