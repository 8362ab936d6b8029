"""``live.ndjson``: a run's steps and trials as JSON lines, appended as they happen.

Every ``forcelearn run`` writes it, so ``forcelearn view DIR`` can follow a run
that another process is making, line by line, and replay a finished one. One
JSON object per line, ``t`` naming its kind, ``w`` the run's wall time (s):

=========  =====================================================================
``meta``   ``meta``: :class:`~forcelearn.tools.live.model.LiveMeta` (again on resume)
``step``   ``trial``, ``phase``, ``row``: the step-log row (as in steps_*.csv)
``trial``  ``record``: the trials.csv row; ``switched``: the phase changed after it
``event``  ``kind``, ``message``: a safety event or incident
``end``    ``error``: null, or why the run stopped early
=========  =====================================================================

A line is written whole and flushed (line buffering), so a reader sees whole
lines and at most one partial last line, which it keeps for the next read.
Runs from before the journal (and contour runs) are read from trials.csv,
summary.json and the steps_*.csv logs instead (:func:`load_run_directory`).
"""

from __future__ import annotations

import csv
import json
import logging
import math
import threading
from pathlib import Path
from typing import IO, Any

from forcelearn.tools.live.model import TRIAL_FIELDS, LiveMeta, LiveModel
from forcelearn.trainer import TrialRecord

log = logging.getLogger(__name__)

JOURNAL = "live.ndjson"


class JournalWriter:
    """Appends the lines of ``live.ndjson``; closing twice is harmless."""

    def __init__(self, path: Path):
        self.path = path
        self._file: IO[str] | None = open(path, "a", buffering=1, encoding="utf-8")  # noqa: SIM115

    def write(self, line: dict[str, Any]) -> None:
        """Append one line (NaN written as null)."""
        if self._file is not None:
            self._file.write(json.dumps(line, separators=(",", ":")) + "\n")

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> JournalWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _record(data: dict[str, Any]) -> TrialRecord:
    values = {name: data[name] for name in TRIAL_FIELDS if name in data}
    if values.get("cell_time_s") is None:
        values["cell_time_s"] = math.nan
    for name in ("mean_r", "force_rms_n", "start_force_n"):
        if values.get(name) is None:
            values[name] = math.nan
    return TrialRecord(**values)


def apply_line(model: LiveModel, line: dict[str, Any]) -> bool:
    """Apply one journal line to the model; True when it ends the run."""
    line_type, wall_s = line.get("t"), float(line.get("w") or 0.0)
    if line_type == "meta":  # a run (re)starts: a resumed run appends to its journal
        model.reopen()
    elif line_type == "step":
        row = {k: (math.nan if v is None else v) for k, v in line["row"].items()}
        model.step(int(line["trial"]), str(line["phase"]), row, wall_s)
    elif line_type == "trial":
        model.trial(_record(line["record"]), bool(line.get("switched")), wall_s)
    elif line_type == "event":
        model.event(str(line["kind"]), str(line["message"]), wall_s)
    elif line_type == "end":
        model.finish(wall_s, line.get("error"))
        return True
    return False


def read_meta(path: Path) -> LiveMeta | None:
    """The meta of the journal's first line (None when absent or unreadable)."""
    try:
        with open(path, encoding="utf-8") as file:
            first = json.loads(file.readline())
    except (OSError, ValueError):
        return None
    return LiveMeta.from_json(first["meta"]) if first.get("t") == "meta" else None


def replay_until_trial(path: Path, model: LiveModel, trial: int) -> None:
    """Apply ``path``'s lines to ``model`` up to the record of trial index ``trial``, not it.

    The model is then what the run's live page showed as that trial's last
    step was drawn (its steps present, its row not yet in the learning curve).

    Raises:
        ValueError: the journal holds no record of that trial (the message says
            how many it holds).
    """
    recorded = 0
    with open(path, encoding="utf-8") as file:
        for raw in file:
            try:
                line = json.loads(raw)
            except ValueError:
                log.warning("%s: skipped a line that is not JSON", path)
                continue
            if line.get("t") == "trial":
                if int(line["record"]["index"]) == trial:
                    return
                recorded += 1
            apply_line(model, line)
    raise ValueError(
        f"{path} records {recorded} trials and not trial index {trial}: choose an earlier trial"
    )


class JournalFollower:
    """Feeds a model from ``live.ndjson``: what is there now, then new lines as they come."""

    def __init__(self, path: Path, model: LiveModel, poll_s: float = 0.2):
        self.path, self.model, self.poll_s = path, model, poll_s
        self._offset = 0
        self._partial = ""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.ended = False

    def read_available(self) -> int:
        """Apply every whole line written since the last call; return how many."""
        with open(self.path, encoding="utf-8") as file:
            file.seek(self._offset)
            chunk = file.read()
            self._offset = file.tell()
        text = self._partial + chunk
        lines = text.split("\n")
        self._partial = lines.pop()
        for raw in lines:
            if not raw.strip():
                continue
            try:
                line = json.loads(raw)
            except ValueError:
                log.warning("%s: skipped a line that is not JSON", self.path)
                continue
            self.ended = apply_line(self.model, line) or self.ended
        return len(lines)

    def start(self) -> None:
        """Read what is there, then follow the file in a daemon thread until it ends."""
        self.read_available()
        if not self.ended:
            self._thread = threading.Thread(target=self._follow, name="live-journal", daemon=True)
            self._thread.start()

    def _follow(self) -> None:
        while not self.ended and not self._stop.wait(self.poll_s):
            self.read_available()

    def close(self) -> None:
        """Stop following."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()


def _read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as file:
        return list(csv.DictReader(file))


def _number(text: str) -> float:
    if text in ("True", "False"):
        return float(text == "True")
    return float(text) if text != "" else math.nan


def load_run_directory(folder: Path) -> LiveModel:
    """A model of a finished run without a journal: trials.csv, summary.json, steps_*.csv."""
    summary = json.loads((folder / "summary.json").read_text())
    logs = {
        name: _read_csv(folder / f"steps_{name}.csv")
        for name in ("first", "switch", "mid", "final")
        if (folder / f"steps_{name}.csv").exists()
    }
    steps = max((len(rows) for rows in logs.values()), default=20)
    trials = _read_csv(folder / "trials.csv")
    meta = LiveMeta(
        task=str(summary.get("task", "?")),
        desired_force_n=float(summary.get("desired_force_n") or math.nan),
        steps_per_trial=steps,
        trials_target=int(summary.get("trials", len(trials))),
        source="view",
    )
    model = LiveModel(meta)
    switch = summary.get("phase_switch_trial")
    wall_total = float(summary.get("wall_s") or 0.0)
    first_rows = [{k: _number(v) for k, v in row.items()} for row in logs.get("first", [])]
    final_rows = [{k: _number(v) for k, v in row.items()} for row in logs.get("final", [])]
    for i, row in enumerate(trials):
        record = _record(
            {
                name: (row[name] == "True" if name == "failed" else _cast(name, row[name]))
                for name in TRIAL_FIELDS
                if name in row
            }
        )
        rows = first_rows if i == 0 else final_rows if i == len(trials) - 1 else []
        for step_row in rows:
            model.step(record.index, record.phase, step_row, wall_total)
        model.trial(record, switch == record.index, wall_total)
    model.finish(wall_total)
    return model


def _cast(name: str, text: str) -> Any:
    if name in ("index", "steps"):
        return int(text)
    if name == "phase":
        return text
    return _number(text)
