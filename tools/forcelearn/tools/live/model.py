"""What the live page shows, as plain data: fed step by step and trial by trial, read as JSON.

The model is pure (no I/O, no clock: callers pass the wall time) and
thread-safe: the run's thread publishes, the server's threads take
snapshots. A publication is a lock, a few appends and a counter increment,
so the run never waits for a page. Memory is bounded by the run itself:
one row per trial for the learning curve, and the step rows of four trials
(present, previous, best, first).

Snapshot (``/api/state``), all indices 0-based as in trials.csv:

==============  ================================================================
``meta``        task, desired_force_n, band (0.05), steps_per_trial, trials_target,
                devices, geometry (contour: circle centre and radius, m)
``version``     publications so far (one per step, trial or event)
``epoch``       changes when trials were replaced (a resumed run redoing a trial)
``trials``      ``since`` and one list per trials.csv column from ``since`` on
``present``     the trial in progress: ``trial``, ``phase``, ``rows`` (step-log rows)
``previous``    the last finished trial, same shape; ``best`` the finished trial
                with the lowest force RMS that completed the path; ``first`` trial 0
``marks``       phase_switch_trial, converged_trial, failures
``status``      trial, phase, trials_done, trials_target, steps, wall_s,
                cell_time_s, steps_per_s, last_safety, finished, error, dropped_updates
``events``      the last safety events and incidents (bounded)
==============  ================================================================
"""

from __future__ import annotations

import dataclasses
import math
import threading
from collections import deque
from typing import Any

from forcelearn.trainer import CONVERGENCE_TOLERANCE, CONVERGENCE_WINDOW, TrialRecord

TRIAL_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(TrialRecord))
"""The columns of trials.csv, in its order."""
BAND = 0.05
"""Half-width of the desired-force band drawn on the page, fraction of the desired force."""
MAX_EVENTS = 50
"""Safety events and incidents kept for the page."""


def json_safe(value: Any) -> Any:
    """Replace NaN and infinities (not valid JSON) by None, recursively."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


@dataclasses.dataclass(frozen=True)
class LiveMeta:
    """Facts about the run that do not change while it goes."""

    task: str
    desired_force_n: float
    steps_per_trial: int
    trials_target: int
    devices: tuple[str, ...] = ()
    geometry: dict[str, Any] | None = None
    """Contour task: ``centre_m`` [x, y] and ``radius_m`` of the disc."""
    source: str = "live"
    """``live`` (the run serves its own page) or ``view`` (read from a run directory)."""

    def to_json(self) -> dict[str, Any]:
        """The meta as a JSON-ready dict (with the band)."""
        data = dataclasses.asdict(self)
        data["devices"] = list(self.devices)
        data["band"] = BAND
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> LiveMeta:
        """Read a meta written by :meth:`to_json`."""
        names = {f.name for f in dataclasses.fields(cls)}
        fields = {k: v for k, v in data.items() if k in names}
        fields["devices"] = tuple(fields.get("devices", ()))
        return cls(**fields)


def _trace(trial: int, phase: str, rows: list[dict[str, float]]) -> dict[str, Any]:
    return {"trial": trial, "phase": phase, "rows": rows}


class LiveModel:
    """The state of one run as the page shows it; see the module docstring for the JSON."""

    def __init__(self, meta: LiveMeta):
        self.meta = meta
        self._lock = threading.Lock()
        self.version = 0
        self.epoch = 0
        self._records: list[TrialRecord] = []
        self._columns: dict[str, list[Any]] = {name: [] for name in TRIAL_FIELDS}
        self._present: dict[str, Any] | None = None
        self._previous: dict[str, Any] | None = None
        self._best: dict[str, Any] | None = None
        self._best_rms = math.inf
        self._first: dict[str, Any] | None = None
        self._switch: int | None = None
        self._converged: int | None = None
        self._good_run = 0
        self._failures = 0
        self._steps = 0
        self._wall_s = 0.0
        self._cell_time_s = 0.0
        self._events: deque[dict[str, Any]] = deque(maxlen=MAX_EVENTS)
        self._last_safety: dict[str, Any] | None = None
        self._finished = False
        self._error: str | None = None
        self.dropped_updates = 0
        """Publications that no page saw as a frame of its own (folded into a later frame)."""

    # ---- publishing (the run's thread) -------------------------------------------------

    def step(self, trial: int, phase: str, row: dict[str, float], wall_s: float) -> None:
        """One step of trial ``trial`` ended with this step-log row (copied)."""
        with self._lock:
            present = self._present
            if present is None or present["trial"] != trial or row.get("step") == 1.0:
                present = self._present = _trace(trial, phase, [])
            present["rows"].append(dict(row))
            self._steps += 1
            self._wall_s = wall_s
            if row.get("limit_hit", 0.0):
                self._add_event(
                    "ForceLimitExceeded",
                    f"force {row.get('force_n', math.nan):.1f} N passed the limit",
                    trial,
                    int(row.get("step", 0)),
                )
            self.version += 1

    def trial(self, record: TrialRecord, switched: bool, wall_s: float) -> None:
        """Trial ``record.index`` ended (``switched``: the phase changed after it)."""
        with self._lock:
            if record.index < len(self._records):
                self._truncate(record.index)
            self._records.append(record)
            for name in TRIAL_FIELDS:
                self._columns[name].append(getattr(record, name))
            if switched:
                self._switch = record.index
            self._failures += record.failed
            if math.isfinite(record.cell_time_s):
                self._cell_time_s += record.cell_time_s
            self._update_converged(record)
            present = self._present
            if present is not None and present["trial"] == record.index:
                finished = _trace(record.index, record.phase, present["rows"])
                self._previous = finished
                if record.index == 0:
                    self._first = finished
                complete = not record.failed and record.steps == self.meta.steps_per_trial
                if complete and record.force_rms_n < self._best_rms:
                    self._best, self._best_rms = finished, record.force_rms_n
            self._wall_s = wall_s
            self.version += 1

    def event(self, kind: str, message: str, wall_s: float | None = None) -> None:
        """A safety event or incident outside the step rows (SensorStale, Ctrl-C ...)."""
        with self._lock:
            present = self._present
            trial = present["trial"] if present else len(self._records)
            step = len(present["rows"]) if present else 0
            self._add_event(kind, message, trial, step)
            if wall_s is not None:
                self._wall_s = wall_s
            self.version += 1

    def finish(self, wall_s: float | None = None, error: str | None = None) -> None:
        """The run ended (``error``: why it stopped early)."""
        with self._lock:
            self._finished = True
            self._error = error
            if wall_s is not None:
                self._wall_s = wall_s
            self.version += 1

    def reopen(self) -> None:
        """A finished run goes on (resumed)."""
        with self._lock:
            self._finished, self._error = False, None
            self.version += 1

    def count_dropped(self, publications: int) -> None:
        """Count publications a page skipped (the server calls this)."""
        with self._lock:
            self.dropped_updates += publications

    # ---- reading (the server's threads) ------------------------------------------------

    def snapshot(self, since: int = 0) -> dict[str, Any]:
        """The page's state as JSON-ready data, with trials from ``since`` on."""
        with self._lock:
            since = max(0, min(since, len(self._records)))
            present = self._present
            trials_done = len(self._records)
            status = {
                "trial": present["trial"] if present else trials_done,
                "phase": present["phase"] if present else None,
                "trials_done": trials_done,
                "trials_target": self.meta.trials_target,
                "steps": self._steps,
                "wall_s": self._wall_s,
                "cell_time_s": self._cell_time_s,
                "steps_per_s": self._steps / self._wall_s if self._wall_s > 0 else None,
                "last_safety": self._last_safety,
                "finished": self._finished,
                "error": self._error,
                "dropped_updates": self.dropped_updates,
            }
            data = {
                "meta": self.meta.to_json(),
                "version": self.version,
                "epoch": self.epoch,
                "trials": {
                    "since": since,
                    **{name: column[since:] for name, column in self._columns.items()},
                },
                "present": _copy_trace(present),
                "previous": _copy_trace(self._previous),
                "best": _copy_trace(self._best),
                "first": _copy_trace(self._first),
                "marks": {
                    "phase_switch_trial": self._switch,
                    "converged_trial": self._converged,
                    "failures": self._failures,
                },
                "status": status,
                "events": list(self._events),
            }
        safe: dict[str, Any] = json_safe(data)  # a dict stays a dict
        return safe

    # ---- internals (lock held) ---------------------------------------------------------

    def _add_event(self, kind: str, message: str, trial: int, step: int) -> None:
        event = {"kind": kind, "message": message, "trial": trial, "step": step}
        self._events.append(event)
        self._last_safety = event

    def _update_converged(self, record: TrialRecord) -> None:
        """The trainer's convergence rule, kept incrementally (O(1) per trial)."""
        limit = CONVERGENCE_TOLERANCE * abs(self.meta.desired_force_n)
        good = (
            not record.failed
            and record.steps == self.meta.steps_per_trial
            and record.force_rms_n <= limit
        )
        self._good_run = self._good_run + 1 if good else 0
        if self._converged is None and self._good_run == CONVERGENCE_WINDOW:
            self._converged = record.index - CONVERGENCE_WINDOW + 1

    def _truncate(self, count: int) -> None:
        """Forget trials from ``count`` on (a resumed run redoes them) and recount."""
        kept = self._records[:count]
        self._records = []
        self._columns = {name: [] for name in TRIAL_FIELDS}
        self._converged, self._good_run, self._failures, self._cell_time_s = None, 0, 0, 0.0
        if self._switch is not None and self._switch >= count:
            self._switch = None
        for record in kept:
            self._records.append(record)
            for name in TRIAL_FIELDS:
                self._columns[name].append(getattr(record, name))
            self._failures += record.failed
            if math.isfinite(record.cell_time_s):
                self._cell_time_s += record.cell_time_s
            self._update_converged(record)
        for name in ("_previous", "_best", "_first"):
            trace = getattr(self, name)
            if trace is not None and trace["trial"] >= count:
                setattr(self, name, None)
        if self._best is None:
            self._best_rms = math.inf
        self.epoch += 1


def _copy_trace(trace: dict[str, Any] | None) -> dict[str, Any] | None:
    if trace is None:
        return None
    return {"trial": trace["trial"], "phase": trace["phase"], "rows": list(trace["rows"])}
