"""``records.mcap``: a run's moves, bursts and tares (what identifies its cell), trial by trial.

The file is MCAP with JSON-schema channels (docs/records.md), so Foxglove and
PlotJuggler open it with named fields; :func:`read_records` gives the
:mod:`forcelearn.records` values back. Every message's log time is the cell
time (the robot's clock) in ns.

====================  ============================================================
``/step``             one :class:`~forcelearn.records.StepRecord` (a move, and the
                      burst read after it, or null)
``/tare``             one :class:`~forcelearn.records.TareRecord`
``/trial``            the end of a trial: ``{"trial", "steps", "tares"}`` (counts of
                      the messages before it that belong to the trial)
====================  ============================================================

Messages are written unchunked, and after each trial's ``/trial`` message the
file is flushed and fsynced, so a run killed at any instant leaves every
ended trial on disk; the summary and footer are written when the run ends.
A file without its footer (the writer died) is read up to its last whole
trial; the incomplete tail is dropped and reported. A file whose records
cannot be parsed, or whose trial counts do not match, is a
:class:`~forcelearn.errors.RecordsFileError`.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import os
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from forcelearn.errors import RecordsFileError
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TareRecord, TrialRecords

log = logging.getLogger(__name__)

RECORDS_FILE = "records.mcap"
PROBE_TRIAL = -1
"""The trial number of the surface probe's records (written before trial 0)."""
STEP_TOPIC, TARE_TOPIC, TRIAL_TOPIC = "/step", "/tare", "/trial"
MCAP_MAGIC = b"\x89MCAP0\r\n"

_NUMBER = {"type": ["number", "null"]}  # null: not finite (NaN: not measured)
_XYZ = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
_MOVE = {
    "type": "object",
    "properties": {
        "commanded_mm": _XYZ, "reached_mm": _XYZ, "start_s": _NUMBER,
        "in_position_s": _NUMBER, "settled_s": _NUMBER,
    },
}
_BURST = {
    "type": ["object", "null"],
    "properties": {
        "mean_n": _NUMBER, "std_n": _NUMBER, "first_n": _NUMBER, "last_n": _NUMBER,
        "count": {"type": "integer"}, "start_s": _NUMBER, "span_s": _NUMBER,
        "filtered_n": _NUMBER,
        "wrench_mean": {"type": ["array", "null"], "items": _NUMBER},
    },
}
SCHEMAS: dict[str, tuple[str, dict[str, Any]]] = {
    STEP_TOPIC: ("forcelearn.StepRecord", {
        "type": "object",
        "properties": {
            "trial": {"type": "integer"}, "index": {"type": "integer"},
            "stage": {"type": "string"}, "move": _MOVE, "burst": _BURST,
        },
    }),
    TARE_TOPIC: ("forcelearn.TareRecord", {
        "type": "object",
        "properties": {
            "trial": {"type": "integer"}, "time_s": _NUMBER, "position_mm": _XYZ,
            "reading_n": _NUMBER, "accepted": {"type": "boolean"},
        },
    }),
    TRIAL_TOPIC: ("forcelearn.TrialEnd", {
        "type": "object",
        "properties": {
            "trial": {"type": "integer"}, "steps": {"type": "integer"},
            "tares": {"type": "integer"},
        },
    }),
}
"""Each channel's schema name and JSON schema (docs/records.md)."""


def _number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _numbers(values: Iterable[float]) -> list[float | None]:
    return [_number(v) for v in values]


def _float(value: Any) -> float:
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"expected a number, got {value!r}")
    return float(value)


def _xyz(values: Any) -> tuple[float, float, float]:
    x, y, z = (_float(v) for v in values)
    return (x, y, z)


def _int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"expected a whole number, got {value!r}")
    return value


def step_to_json(step: StepRecord) -> dict[str, Any]:
    """A step record as its ``/step`` message (non-finite numbers as null)."""
    move, burst = step.move, step.burst
    return {
        "trial": step.trial,
        "index": step.index,
        "stage": step.stage,
        "move": {
            "commanded_mm": _numbers(move.commanded_mm),
            "reached_mm": _numbers(move.reached_mm),
            "start_s": _number(move.start_s),
            "in_position_s": _number(move.in_position_s),
            "settled_s": _number(move.settled_s),
        },
        "burst": None if burst is None else {
            "mean_n": _number(burst.mean_n),
            "std_n": _number(burst.std_n),
            "first_n": _number(burst.first_n),
            "last_n": _number(burst.last_n),
            "count": burst.count,
            "start_s": _number(burst.start_s),
            "span_s": _number(burst.span_s),
            "filtered_n": _number(burst.filtered_n),
            "wrench_mean": None if burst.wrench_mean is None else _numbers(burst.wrench_mean),
        },
    }


def step_from_json(data: dict[str, Any]) -> StepRecord:
    """The inverse of :func:`step_to_json` (raises KeyError, TypeError or ValueError)."""
    move, burst = data["move"], data["burst"]
    wrench = None if burst is None else burst["wrench_mean"]
    if wrench is not None and len(wrench) != 6:
        raise ValueError(f"wrench_mean has {len(wrench)} values, not 6")
    stage = data["stage"] if "stage" in data else data["kind"]  # "kind": files of 2026-12-03
    if not isinstance(stage, str):
        raise TypeError(f"stage must be text, got {stage!r}")
    return StepRecord(
        trial=_int(data["trial"]),
        index=_int(data["index"]),
        stage=stage,
        move=MoveRecord(
            _xyz(move["commanded_mm"]), _xyz(move["reached_mm"]), _float(move["start_s"]),
            _float(move["in_position_s"]), _float(move["settled_s"]),
        ),
        burst=None if burst is None else BurstRecord(
            mean_n=_float(burst["mean_n"]),
            std_n=_float(burst["std_n"]),
            first_n=_float(burst["first_n"]),
            last_n=_float(burst["last_n"]),
            count=_int(burst["count"]),
            start_s=_float(burst["start_s"]),
            span_s=_float(burst["span_s"]),
            filtered_n=_float(burst["filtered_n"]),
            wrench_mean=None if wrench is None else (
                _float(wrench[0]), _float(wrench[1]), _float(wrench[2]),
                _float(wrench[3]), _float(wrench[4]), _float(wrench[5]),
            ),
        ),
    )


def tare_to_json(tare: TareRecord) -> dict[str, Any]:
    """A tare record as its ``/tare`` message."""
    return {
        "trial": tare.trial,
        "time_s": _number(tare.time_s),
        "position_mm": _numbers(tare.position_mm),
        "reading_n": _number(tare.reading_n),
        "accepted": tare.accepted,
    }


def tare_from_json(data: dict[str, Any]) -> TareRecord:
    """The inverse of :func:`tare_to_json` (raises KeyError, TypeError or ValueError)."""
    accepted = data["accepted"]
    if not isinstance(accepted, bool):
        raise TypeError(f"accepted must be true or false, got {accepted!r}")
    return TareRecord(
        _int(data["trial"]), _float(data["time_s"]), _xyz(data["position_mm"]),
        _float(data["reading_n"]), accepted,
    )


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable where the platform allows it."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _ns(time_s: float) -> int:
    """Cell time (s) as an MCAP log time (ns; 0 for a time not known)."""
    return max(0, round(time_s * 1e9)) if math.isfinite(time_s) else 0


class RecordsWriter:
    """Writes ``records.mcap`` one whole trial at a time (flushed and fsynced per trial).

    Args:
        path: the file to write.
        keep: trials to write first (a resumed run's, read back from the old file).
            The new file is written beside ``path`` and replaces it only once it
            holds them all, so a crash meanwhile leaves the old file.
    """

    def __init__(self, path: Path, keep: Sequence[TrialRecords] = ()) -> None:
        self.path = path
        temporary = path.with_name(f".{path.name}.tmp")
        self._handle: BinaryIO | None = open(temporary, "wb")  # noqa: SIM115 (kept open)
        try:
            self._writer = Writer(self._handle, use_chunking=False)
            self._writer.start(profile="", library="forcelearn")
            self._channels = {
                topic: self._writer.register_channel(
                    topic, "json",
                    self._writer.register_schema(name, "jsonschema", json.dumps(schema).encode()),
                )
                for topic, (name, schema) in SCHEMAS.items()
            }
            for trial in keep:
                self._write(trial)
            self._sync()
            os.replace(temporary, path)
            _fsync_folder(path.parent)
        except BaseException:
            self._handle.close()
            self._handle = None
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)
            raise

    def write_trial(self, trial: TrialRecords) -> None:
        """Append one trial's records and its end, and make them durable."""
        self._write(trial)
        self._sync()

    def _write(self, trial: TrialRecords) -> None:
        last = 0
        for step in trial.steps:
            last = _ns(step.move.settled_s)
            self._add(STEP_TOPIC, step_to_json(step), last)
        for tare in trial.tares:
            self._add(TARE_TOPIC, tare_to_json(tare), _ns(tare.time_s))
        end = {"trial": trial.trial, "steps": len(trial.steps), "tares": len(trial.tares)}
        self._add(TRIAL_TOPIC, end, last)

    def _add(self, topic: str, data: dict[str, Any], time_ns: int) -> None:
        payload = json.dumps(data, allow_nan=False, separators=(",", ":")).encode()
        self._writer.add_message(self._channels[topic], time_ns, payload, time_ns)

    def _sync(self) -> None:
        assert self._handle is not None
        self._handle.flush()
        os.fsync(self._handle.fileno())

    def close(self) -> None:
        """Write the summary and footer and close the file; safe to call twice."""
        if self._handle is None:
            return
        try:
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._sync()
        finally:
            self._handle.close()
            self._handle = None


@dataclass
class RecordsScan:
    """What :func:`scan_records` found in a records file."""

    trials: list[TrialRecords]
    """Every whole trial, in file order."""
    finished: bool
    """True when the file ends with its footer (the writer closed it)."""
    dropped_tail: bool
    """True when an incomplete tail (a trial the writer did not end) was dropped."""


def scan_records(path: Path) -> RecordsScan:
    """Read every whole trial of a records file, recovering one whose writer died.

    Raises:
        RecordsFileError: the file is not a records file, or a record in it is
            damaged (not a truncated tail of an unfinished file).
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecordsFileError(f"cannot read {path}: {exc}") from exc
    finished = len(data) >= 2 * len(MCAP_MAGIC) and data.endswith(MCAP_MAGIC)
    if not data.startswith(MCAP_MAGIC):
        raise RecordsFileError(
            f"{path} is not an MCAP file (its first bytes are not MCAP's magic): it is not a "
            "run's records; move it away to let the run write a new one"
        )
    topics: dict[int, str] = {}
    trials: list[TrialRecords] = []
    pending = TrialRecords(trial=-1)
    stream = io.BytesIO(data)
    records = StreamReader(stream, skip_magic=False).records
    read_to = 0  # the end of the last record read whole, bytes
    dropped = False
    while True:
        try:
            record = next(records, None)
            if record is None:
                break
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Message):
                done = _take(topics.get(record.channel_id), record.data, pending)
                if done is not None:
                    if trials and done.trial <= trials[-1].trial:
                        raise ValueError(f"trial {done.trial} follows trial {trials[-1].trial}")
                    trials.append(done)
                    pending = TrialRecords(trial=-1)
            read_to = stream.tell()
        except (McapError, ValueError, KeyError, TypeError, struct.error) as exc:
            if finished or stream.tell() < len(data):
                why = "a record runs past the end" if isinstance(exc, EndOfFile) else str(exc)
                raise _damaged(path, why) from exc
            # the writer died inside the last record: the tail is dropped
            dropped = read_to < len(data)
            break
    dropped = dropped or bool(pending.steps or pending.tares)
    if dropped:
        log.warning(
            "%s ends inside a trial (its writer stopped there): read its %d whole trials and "
            "dropped the rest", path, len(trials),
        )
    return RecordsScan(trials, finished, dropped)


def _take(topic: str | None, payload: bytes, pending: TrialRecords) -> TrialRecords | None:
    """Add one message to the trial being read; return the trial when this message ends it."""
    if topic not in SCHEMAS:
        return None  # a channel a later version added: not ours to read
    data = json.loads(payload)
    if not isinstance(data, dict):
        raise TypeError(f"a {topic} message is not an object")
    if topic == STEP_TOPIC:
        pending.steps.append(step_from_json(data))
        return None
    if topic == TARE_TOPIC:
        pending.tares.append(tare_from_json(data))
        return None
    trial, steps, tares = _int(data["trial"]), _int(data["steps"]), _int(data["tares"])
    if (steps, tares) != (len(pending.steps), len(pending.tares)):
        raise ValueError(
            f"trial {trial} ends after {steps} steps and {tares} tares, but "
            f"{len(pending.steps)} and {len(pending.tares)} were read"
        )
    if any(s.trial != trial for s in pending.steps) or any(t.trial != trial for t in pending.tares):
        raise ValueError(f"trial {trial} holds records of another trial")
    pending.trial = trial
    return pending


def _damaged(path: Path, why: str) -> RecordsFileError:
    return RecordsFileError(
        f"{path} is damaged ({why}): restore it from a backup, or move it away; a resumed "
        "run then records only the trials it runs from there"
    )


def read_records(run_dir: Path | str, probe: bool = False) -> list[TrialRecords]:
    """Every whole trial a run directory recorded, in trial order (see :func:`scan_records`).

    With ``probe`` the surface probe's records come first, as trial
    :data:`PROBE_TRIAL` (-1; none when the run did not probe).

    Raises:
        RecordsFileError: no records file in ``run_dir``, or a damaged one.
    """
    path = Path(run_dir) / RECORDS_FILE
    if not path.exists():
        raise RecordsFileError(
            f"{path} does not exist: runs write it from this version on; run the trials "
            "again (forcelearn run) to record them"
        )
    trials = scan_records(path).trials
    return trials if probe else [t for t in trials if t.trial != PROBE_TRIAL]
