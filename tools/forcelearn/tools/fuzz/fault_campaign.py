"""Faults in contact: inject device faults at random instants of real §5 runs and judge by physics.

``python -m forcelearn.tools.fuzz.fault_campaign --runs 13 --trials 2 --faults 12 --seed 1``
runs, for each of the four emulated example cells (computer link + JR3, EGM +
JR3, computer link + Net F/T, EGM + Net F/T), ``--runs`` short runs of the
surface experiment (``forcelearn run``'s engine, in this process), each with
``--faults`` faults per device drawn from :mod:`~.fault_inject`'s kinds and
spread over random instants, plus process kills. A killed run, and a run that
ended on a typed error, is resumed as an operator would (``--resume``) until it
completes. Then, from the emulated physics (:class:`~.fault_inject.Truth`):

* the true contact force never passed ``[safety] max_force_n``;
* every zero was taken with no contact;
* every reading the run used was within the tolerance of the true force
  (the tolerance: twice the worst error of a fault-free run of the same cell,
  at least 1 N), charged to the last fault before it. A reading is *used* when
  the run books the trial (or the probe) it belongs to (its records written,
  then its checkpoint); the readings of a trial rolled back (a fault, a void
  by the zero check, a kill) are *voided*, counted apart and never used;
* after every fault that raised, the robot was stopped within the watchdog
  (``stale_sensor_s + move_timeout_s`` of cell time);
* every session that ended on an error ended on one of forcelearn's, with an
  ``ended`` or ``interrupted`` line in ``faults.jsonl``;
* ``records.mcap``, ``trials.csv`` and the checkpoint hold each trial once.

The table it prints is docs/fuzzing.md's "Faults in contact".
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import logging
import pickle
import random
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any
from unittest import mock

import tomli_w

from forcelearn.errors import ForcelearnError
from forcelearn.learning import load_learner
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.fault_recovery import RunRecovery, read_events
from forcelearn.tools.experiments.records import RECORDS_FILE, RecordsWriter, scan_records
from forcelearn.tools.figures import probe as figures_probe
from forcelearn.tools.figures import surface as figures_surface
from forcelearn.tools.fuzz.fault_inject import (
    ROBOT_FAULTS,
    SENSOR_FAULTS,
    Injector,
    Killed,
    Truth,
    cause,
    plan_faults,
    read_to_stop_s,
    stop_latency_s,
)
from forcelearn.tools.fuzz.fault_table import RunReport, table

log = logging.getLogger(__name__)

EXAMPLES = Path(__file__).resolve().parents[4] / "examples"
"""The example cells beside the source tree (an editable install or a checkout)."""


def examples_folder() -> Path:
    """The example cells: beside the source tree, else ./examples (a wheel ships none)."""
    for folder in (EXAMPLES, Path.cwd() / "examples"):
        if (folder / CELLS["link+jr3"]).is_file():
            return folder
    raise FileNotFoundError(
        f"the campaign's cells are the project's examples/ ({', '.join(CELLS.values())}): "
        "run it from a checkout of forcelearn (its top folder holds examples/)"
    )
CELLS = {
    "link+jr3": "emulated-cell.toml",
    "egm+jr3": "egm-cell.toml",
    "link+netft": "netft-cell.toml",
    "egm+netft": "egm-netft-cell.toml",
}
KINDS = {"link": "computer_link", "egm": "egm", "jr3": "jr3", "netft": "netft"}
STALE_SENSOR_S = 0.3
"""The campaign's sensor watchdog, s (the emulated default of 10 s would make silences slow)."""
MOVE_TIMEOUT_S = 2.0
"""The campaign's in-position timeout, s of controller time (10 s by default; a step of
the task takes well under 0.2 s; the probe dwells 1.5 s in its waits)."""
EGM_SPEED_MM_S = 250.0
"""The EGM planned pose's speed in the campaign: the example's ceiling (EGM time is what
the campaign spends most on: every controller cycle is emulated)."""
STEP_S = 1.0
"""Allowance for the step in progress when a fault strikes in contact, s of cell time
(a step of at most ``[safety] max_step_mm`` is far shorter)."""
MAX_SESSIONS = 20
"""Sessions one run may take after its last planned fault before it counts as not finished
(a run resumes as long as faults are still planned: the probe starts over at each session)."""
SESSION_CAP = 200
"""Sessions of one run in all, whatever is still planned."""
READ_SLACK_S = 2.0
"""Wall time a loaded host may add to a read's watchdog (2 x ``stale_sensor_s``), s."""


def cell_config(cell: str, folder: Path, trials: int, steps: int, probe: bool,
                settings: Sequence[str] = ()) -> Path:
    """The example cell's config with the campaign's watchdogs, trials and steps, as a file.

    Without ``probe`` the run starts cold on the fallback map (the probe costs
    most of a short run's time; the first run of each cell keeps it).
    ``settings``: ``table.key=value`` overrides (TOML values), e.g. another
    material: ``emulator.sponge.stiffness_n_per_mm=8``.
    """
    table = _example_table(cell, trials, probe, settings)
    table.setdefault("safety", {})["stale_sensor_s"] = STALE_SENSOR_S
    table.setdefault("safety", {})["move_timeout_s"] = MOVE_TIMEOUT_S
    if table.get("robot", {}).get("kind") == "egm":
        table["robot"]["speed_mm_s"] = EGM_SPEED_MM_S
    table.setdefault("task", {})["steps_per_trial"] = steps
    path = folder / f"{cell.replace('+', '-')}{'-probe' if probe else ''}.toml"
    path.write_text(tomli_w.dumps(table))
    return path


def examples_config(cell: str, folder: Path, trials: int, probe: bool,
                    settings: Sequence[str] = ()) -> Path:
    """The example cell's config as it is, but ``trials``, ``probe`` and ``settings``, as a file."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{cell.replace('+', '-')}{'-probe' if probe else ''}.toml"
    path.write_text(tomli_w.dumps(_example_table(cell, trials, probe, settings)))
    return path


def _example_table(cell: str, trials: int, probe: bool, settings: Sequence[str]) -> dict[str, Any]:
    """The example cell's config table with the overrides (see :func:`cell_config`)."""
    table = tomllib.loads((examples_folder() / CELLS[cell]).read_text())
    for setting in settings:
        name, _, value = setting.partition("=")
        *tables, key = name.strip().split(".")
        place = table
        for name in tables:
            place = place.setdefault(name, {})
        place[key] = tomllib.loads(f"v = {value}")["v"]
    table.setdefault("probe", {})["enabled"] = probe
    if not probe:
        table.setdefault("run", {})["learner_start"] = "cold"
    table.setdefault("run", {})["trials"] = trials
    return table


@contextlib.contextmanager
def injecting(injector: Injector | None, tolerance_n: float,
              truths: list[Truth]) -> Iterator[None]:
    """Make the run engine open sessions watched by a :class:`Truth` (and ``injector``)."""

    class Session(CellSession):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            assert self.cell is not None
            truth = Truth(self, tolerance_n, self.cell.force_filter.measurement_variance_n2 ** 0.5)
            truths.append(truth)
            if injector is not None:
                injector.attach(self, truth)

    write_trial, void = RecordsWriter.write_trial, RunRecovery._void

    def booked(writer: RecordsWriter, trial: Any) -> None:
        truths[-1].commit()  # the trial (or probe) is kept: its readings are used
        write_trial(writer, trial)

    def voided(recovery: RunRecovery, trial: int, exc: ForcelearnError) -> None:
        truths[-1].void()  # rolled back: its readings are set aside
        void(recovery, trial, exc)

    with mock.patch.object(engine, "CellSession", Session), \
            mock.patch.object(RecordsWriter, "write_trial", booked), \
            mock.patch.object(RunRecovery, "_void", voided), \
            mock.patch.object(figures_surface, "write_all", _no_figure), \
            mock.patch.object(figures_probe, "write_probe_figure", _no_figure):
        yield


def _no_figure(*args: Any, **kwargs: Any) -> None:
    """The campaign draws no figures (they cost seconds a run and judge nothing)."""


def fault_free_run(config: Path, folder: Path, seed: int) -> tuple[int, float, float]:
    """(device calls, worst reading error N, max contact N) of one run without faults."""
    truths: list[Truth] = []
    counter = Injector({}, random.Random(0))
    with injecting(counter, 1e9, truths):
        run, checkpoint = run_state.prepare_run(config, folder, None, seed, resume=False)
        engine.execute(run, checkpoint)
    truth = truths[0]
    return counter.tick, truth.worst_error_n, truth.max_contact_n


def report_row(report: RunReport, ticks: int, free_max_n: float) -> dict[str, Any]:
    """The judged figures of one run as a CSV row's columns (the sweeps' shared part); N."""
    return {
        "of_ticks": ticks, "max_contact_n": round(report.max_contact_n, 2),
        "free_max_contact_n": round(free_max_n, 2), "over_limit": report.over_limit,
        "beyond_3sigma": report.beyond_3sigma, "worst_used_n": round(report.worst_used_n, 3),
        "zeros_in_contact": report.zeros_in_contact, "sessions": report.sessions,
        "finished": report.finished, "ends": dict(report.typed_ends),
        "resumed_from": dict(report.resumed_from),
    }


def one_run(cell: str, config: Path, folder: Path, seed: int, ticks: int, faults: int,
            kills: int, tolerance_n: float, devices: Sequence[str] = ("robot", "sensor"),
            injector: Injector | None = None) -> RunReport:
    """One run with its faults, resumed until it completes; judged from the physics.

    ``faults`` faults on each of ``devices`` ("robot", "sensor"), kinds drawn at random;
    or ``injector``'s own plan (then ``ticks``, ``faults`` and ``kills`` are not used).
    """
    report = RunReport(cell, seed)
    rng = random.Random(seed)
    robot, sensor = cell.split("+")
    counts = {("robot", kind): 0 for kind in ROBOT_FAULTS}
    counts |= {("sensor", kind): 0 for kind in SENSOR_FAULTS}
    kinds = {"robot": ROBOT_FAULTS, "sensor": SENSOR_FAULTS}
    for _ in range(faults):
        for device in devices:
            counts[(device, rng.choice(kinds[device]))] += 1
    counts[("run", "kill")] = kills
    if injector is None:
        injector = Injector(plan_faults(rng, ticks, counts), rng)
    injector.events = lambda: len(read_events(folder))
    truths: list[Truth] = []
    started = time.perf_counter()
    resume = False
    with injecting(injector, tolerance_n, truths):
        left = report.sessions  # sessions after the last planned fault fired
        while left < MAX_SESSIONS and report.sessions < SESSION_CAP:
            report.sessions += 1
            left = left + 1 if not injector.plan else 0
            try:
                run, checkpoint = run_state.prepare_run(
                    None if resume else config, folder, None, None if resume else seed, resume
                )
                engine.execute(run, checkpoint)
                report.finished = True
                break
            except Killed:
                report.typed_ends["kill"] += 1
            except ForcelearnError as exc:
                report.typed_ends[type(exc).__name__] += 1
                last = read_events(folder)[-1:] or [{}]
                if last[0].get("action") not in ("ended", "interrupted"):
                    report.problems.append(f"{type(exc).__name__} without an ended event")
                    report.untyped_ends += 1
            except Exception as exc:  # a foreign error: a finding
                report.untyped_ends += 1
                report.problems.append(f"untyped end: {type(exc).__name__}: {exc}")
            # killed or ended before the first checkpoint: a new run in the same folder
            resume = (folder / run_state.CHECKPOINT).exists()
    report.wall_s = time.perf_counter() - started
    _judge(report, injector, truths, folder, robot, sensor)
    return report


def _judge(report: RunReport, injector: Injector, truths: list[Truth], folder: Path,
           robot: str, sensor: str) -> None:
    """Fill the report from the truth watchers, the injector's log and the run directory."""
    config = load_cell_config(folder / run_state.CONFIG_COPY)
    limit_n = config.safety.max_force_n
    bound_s = config.safety.stale_sensor_s + config.safety.move_timeout_s + STEP_S
    read_bound_s = 2 * config.safety.stale_sensor_s + READ_SLACK_S
    for truth in truths:
        truth.finish()
        report.voided += truth.voided
        report.voided_bad.update(truth.voided_bad)
        report.worst_used_n = max(report.worst_used_n, truth.worst_used_n)
        report.max_contact_n = max(report.max_contact_n, truth.max_contact_n)
        report.over_limit += truth.max_contact_n > limit_n
        report.zeros += truth.zeros
        report.zeros_in_contact += truth.zeros_in_contact
        report.readings += truth.readings
        report.beyond_3sigma += truth.beyond_3sigma
        report.sigma_n = truth.sigma_n
        report.bad_readings.update(truth.bad_readings)
    names = {"robot": KINDS[robot], "sensor": KINDS[sensor], "run": "run"}
    events = read_events(folder)
    for fired in injector.fired:
        report.fired[(names[fired.device], fired.kind)] += 1
    for index, event in enumerate(events):
        if event["action"] not in ("resumed", "ended", "voided"):
            continue
        found = cause(event["error"], injector.fired, index)
        if found is None:
            continue
        fired = found
        if event["action"] in ("resumed", "voided"):
            report.resumed_from[f"{names[fired.device]}:{fired.kind}"] += 1
        if event["action"] == "voided":  # unseen until free space: the trial's end, not a stop
            report.voids += 1
            continue
        if not fired.in_contact:  # in free space a fault is found at the next read
            continue
        if fired.device == "sensor":  # found at the next read, stopped by its watchdog
            latency, unread = read_to_stop_s(fired, injector.stops, injector.reads)
            report.worst_read_stop_s = max(report.worst_read_stop_s, latency or 0.0)
            report.worst_unread_s = max(report.worst_unread_s, unread)
            bound = read_bound_s
        else:
            latency = stop_latency_s(fired, injector.stops)
            report.worst_stop_s = max(report.worst_stop_s, latency or 0.0)
            bound = bound_s
        if latency is None or latency > bound:
            report.late_stops += 1
            report.problems.append(f"{fired.kind}: stopped after {latency} s (bound {bound})")
    if report.typed_ends["kill"] and report.finished:
        report.resumed_from["run:kill"] += report.typed_ends["kill"]
    report.lost_or_duplicated = _records_problems(folder, report)


def _records_problems(folder: Path, report: RunReport) -> int:
    """Trials missing or twice in records.mcap, trials.csv or the checkpoint."""
    if not (folder / run_state.CHECKPOINT).exists():
        return 0
    done = int(load_learner(folder / run_state.CHECKPOINT)[1]["trials_done"])
    with open(folder / "trials.csv", newline="") as handle:
        rows = [int(row["index"]) for row in csv.DictReader(handle)]
    recorded = [t.trial for t in scan_records(folder / RECORDS_FILE).trials if t.trial >= 0]
    problems = 0
    for name, seen in (("trials.csv", rows), ("records.mcap", recorded)):
        if sorted(seen) != list(range(done)):
            problems += 1
            report.problems.append(f"{name} holds trials {sorted(seen)}, checkpoint {done}")
    return problems


def campaign(cells: Sequence[str], runs: dict[str, int], trials: int, steps: int,
             faults: dict[str, int], kills: int, seed: int, folder: Path,
             save: Path | None = None, devices: Sequence[str] = ("robot", "sensor"),
             replay: Sequence[int] = (), settings: Sequence[str] = ()) -> list[RunReport]:
    """Every cell, ``runs[robot]`` runs of ``faults[robot]`` faults per device; a line per run.

    With ``save``, the reports so far are pickled there after every run. With
    ``replay``, only those run seeds (``seed·1000 + 100·cell + run``, as printed) run.
    """
    reports: list[RunReport] = []
    if replay:
        cells = [cell for i, cell in enumerate(CELLS) if any(r // 100 % 10 == i for r in replay)]
    for cell in cells:
        config = cell_config(cell, folder, trials, steps, probe=False, settings=settings)
        probed = cell_config(cell, folder, trials, steps, probe=True, settings=settings)
        ticks, worst_n, contact_n = fault_free_run(config, folder / f"{cell}-free", seed)
        probe_ticks = fault_free_run(probed, folder / f"{cell}-free-probe", seed)[0]
        tolerance_n = max(1.0, 2.0 * worst_n)
        print(f"{cell}: fault-free run: {ticks} device calls, worst reading error "
              f"{worst_n:.2f} N (tolerance {tolerance_n:.2f} N), max contact {contact_n:.1f} N",
              flush=True)
        robot = cell.split("+")[0]
        wanted = [r for r in replay if r // 100 % 10 == list(CELLS).index(cell)]
        for k in [r % 100 for r in wanted] if replay else range(runs[robot]):
            run_seed = (wanted[0] // 1000 if replay else seed) * 1000 \
                + 100 * list(CELLS).index(cell) + k
            first = k == 0
            report = one_run(cell, probed if first else config, folder / f"{cell}-{k}",
                             run_seed, probe_ticks if first else ticks, faults[robot], kills,
                             tolerance_n, devices)
            reports.append(report)
            if save is not None:
                save.write_bytes(pickle.dumps(reports))
            print(f"{cell} run {k} seed {run_seed}: {sum(report.fired.values())} faults, "
                  f"{report.sessions} sessions, finished {report.finished}, max contact "
                  f"{report.max_contact_n:.1f} N, zeros in contact {report.zeros_in_contact}, "
                  f"bad readings {dict(report.bad_readings)} of {report.readings} used "
                  f"({report.beyond_3sigma} beyond 3 sigma, worst {report.worst_used_n:.2f} N) "
                  f"(voided {report.voided}, {sum(report.voided_bad.values())} off; "
                  f"{report.voids} voids), late stops {report.late_stops}, "
                  f"records {report.lost_or_duplicated}, ends {dict(report.typed_ends)}, "
                  f"resumed from {dict(report.resumed_from)}, {report.wall_s:.0f} s"
                  + (f"; {report.problems}" if report.problems else ""), flush=True)
    return reports


def main(argv: Sequence[str] | None = None) -> int:
    """Run the campaign and print the table; status 1 when a check failed."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.fuzz.fault_campaign",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--cells", nargs="*", default=list(CELLS), choices=list(CELLS))
    parser.add_argument("--runs", type=int, default=18, help="runs per computer-link cell")
    parser.add_argument("--runs-egm", type=int, default=8, help="runs per EGM cell")
    parser.add_argument("--trials", type=int, default=2, help="trials per run")
    parser.add_argument("--steps", type=int, default=8, help="steps per trial")
    parser.add_argument("--faults", type=int, default=40,
                        help="faults per device per run, computer-link cells")
    parser.add_argument("--faults-egm", type=int, default=63,
                        help="faults per device per run, EGM cells (their runs cost more)")
    parser.add_argument("--kills", type=int, default=1, help="process kills per run")
    parser.add_argument("--devices", nargs="+", default=["robot", "sensor"],
                        choices=["robot", "sensor"], help="the devices that fail")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--set", dest="settings", action="append", default=[],
                        metavar="TABLE.KEY=VALUE",
                        help="override a setting of every cell (TOML value), e.g. "
                             "emulator.sponge.stiffness_n_per_mm=8")
    parser.add_argument("--keep", type=Path, default=None, help="keep the run folders here")
    parser.add_argument("--save", type=Path, default=None,
                        help="save the reports (pickle) for --merge")
    parser.add_argument("--replay", type=int, nargs="*", default=[],
                        help="run only these run seeds (as printed), with the other options")
    parser.add_argument("--merge", type=Path, nargs="*", default=None,
                        help="print the table of saved reports instead of running")
    args = parser.parse_args(argv)
    if args.merge is not None:
        merged = [r for path in args.merge for r in pickle.loads(path.read_bytes())]
        print(table(merged))
        return 1 if _failed(merged) else 0
    logging.basicConfig(level=logging.CRITICAL)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        reports = campaign(args.cells, {"link": args.runs, "egm": args.runs_egm}, args.trials,
                           args.steps, {"link": args.faults, "egm": args.faults_egm},
                           args.kills, args.seed, folder, args.save, args.devices,
                           args.replay, args.settings)
    print(table(reports))
    return 1 if _failed(reports) else 0


def _failed(reports: Sequence[RunReport]) -> bool:
    """True when a run broke a check (an unfinished run that ended typed is not a failure)."""
    return any(r.over_limit or r.zeros_in_contact or r.lost_or_duplicated or r.untyped_ends
               or r.late_stops for r in reports)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
