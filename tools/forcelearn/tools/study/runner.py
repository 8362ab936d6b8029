"""Run a study's runs on local processes or a Dask cluster, resumably, with a progress bar.

One code path for both: the runs are cut into chunks (a batch of runs that
share a chunk key, e.g. many seeds of the §4 simulation), chunks are submitted
to a ``concurrent.futures.Executor`` (a local ``ProcessPoolExecutor``, or the
executor of a ``distributed.Client`` connected to ``--scheduler``), and every
finished run is written to ``runs/<run_id>.json`` by this process as its chunk
returns (with ``runs/<run_id>.npz``, its per-trial curves, when the task gives
them). A restarted study skips the runs whose JSON file exists.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import (
    Executor,
    Future,
    ProcessPoolExecutor,
    ThreadPoolExecutor,
    as_completed,
)
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from tqdm import tqdm

from forcelearn.atomic import atomic_write_bytes, atomic_writer
from forcelearn.errors import StudyError
from forcelearn.tools.study.grid import CURVES, RunSpec, Value, format_value, run_specs
from forcelearn.tools.study.report import write_tables
from forcelearn.tools.study.tasks import StudyTask

RUNS_DIR = "runs"
MANIFEST = "study.json"
DEFAULT_BATCH = 32
"""Most runs per chunk of a batched task."""


@dataclass
class StudyOutcome:
    """What a study call did: every row of the study, and how many runs it ran or reused."""

    rows: list[dict[str, Any]]
    ran: int
    reused: int
    files: list[Path]


class _DaskClient(Protocol):
    """The part of ``distributed.Client`` used here (Dask does not annotate these methods)."""

    def __enter__(self) -> Any: ...

    def __exit__(self, exc_type: Any, exc_value: Any, traceback: Any) -> Any: ...

    def nthreads(self) -> Mapping[str, int]: ...

    def get_executor(self) -> Executor: ...


@contextlib.contextmanager
def open_executor(workers: int | None, scheduler: str | None) -> Iterator[tuple[Executor, int]]:
    """Yield an executor and its number of parallel slots.

    ``scheduler`` (``tcp://host:8786``) connects to a running Dask cluster (needs
    ``pip install 'forcelearn[cluster]'``); otherwise local processes, ``workers``
    of them (all cores by default; 1 runs in this process, in a thread).
    """
    if scheduler:
        try:
            from distributed import Client
        except ImportError as exc:
            raise StudyError(
                "--scheduler needs Dask's distributed package: pip install 'forcelearn[cluster]'"
            ) from exc
        connect: Callable[..., _DaskClient] = Client
        try:
            client = connect(scheduler, timeout=30)
        except OSError as exc:
            raise StudyError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from exc
        with client:
            slots = sum(client.nthreads().values()) or 1
            executor = client.get_executor()
            yield executor, slots
        return
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise StudyError(f"--workers must be >= 1, got {workers}")
    pool: Executor = ThreadPoolExecutor(1) if workers == 1 else ProcessPoolExecutor(workers)
    with pool:
        yield pool, workers


def make_chunks(
    task: StudyTask, specs: Sequence[RunSpec], slots: int, batch: int
) -> list[list[RunSpec]]:
    """Cut the runs into chunks: per chunk key, at most ``batch`` runs, spread over ``slots``."""
    chunks = _chunks(task, specs, slots, batch)
    if task.cost is not None:  # costliest first: the last to end are short
        cost = task.cost
        chunks.sort(key=lambda chunk: -sum(cost(s) for s in chunk))
    return chunks


def _chunks(
    task: StudyTask, specs: Sequence[RunSpec], slots: int, batch: int
) -> list[list[RunSpec]]:
    """:func:`make_chunks` in grid order."""
    if not task.batched:
        return [[s] for s in specs]
    groups: dict[Any, list[RunSpec]] = {}
    for spec in specs:
        groups.setdefault(task.group_key(spec), []).append(spec)
    chunks = []
    total = len(specs)
    for members in groups.values():
        # Chunks in multiples of the slots, so the last round keeps every slot busy.
        share = max(1, math.ceil(slots * len(members) / total))
        rounds = math.ceil(len(members) / (share * batch))
        size = max(1, math.ceil(len(members) / (share * rounds)))
        chunks += [members[i : i + size] for i in range(0, len(members), size)]
    return chunks


def run_study(
    task: StudyTask,
    out: Path,
    trials: int,
    seeds: Sequence[int],
    points: Sequence[Mapping[str, Value]],
    workers: int | None = None,
    scheduler: str | None = None,
    batch: int = DEFAULT_BATCH,
    progress: bool = True,
    command: str = "",
    on_chunk: Callable[[list[dict[str, Any]]], Any] | None = None,
) -> StudyOutcome:
    """Run every (point, seed) not yet done in ``out``, then write the tables and figures.

    ``on_chunk(rows)`` is called after each chunk's rows are saved (tests use it to
    interrupt a study).
    """
    runs_dir = out / RUNS_DIR
    runs_dir.mkdir(parents=True, exist_ok=True)
    specs = list(run_specs(task.name, trials, seeds, points))
    keys = list(points[0]) if points else []
    manifest = {
        "task": task.name,
        "trials": trials,
        "seeds": list(seeds),
        "keys": keys,
        "points": [{k: format_value(v) for k, v in p.items()} for p in points],
        "command": command,
    }
    atomic_write_bytes(out / MANIFEST, (json.dumps(manifest, indent=2) + "\n").encode())
    todo = [s for s in specs if not (runs_dir / f"{s.run_id}.json").exists()]
    ran = 0
    bar = tqdm(
        total=len(specs),
        initial=len(specs) - len(todo),
        unit="run",
        disable=not progress,
        dynamic_ncols=True,
        desc=f"study {task.name}",
    )

    def save(rows: list[dict[str, Any]]) -> None:
        nonlocal ran
        for row in rows:
            curves = row.pop(CURVES, None)
            if curves is not None:
                with atomic_writer(runs_dir / f"{row['run_id']}.npz") as handle:
                    arrays = {k: np.asarray(v) for k, v in curves.items()}
                    # numpy's default allow_pickle, named: mypy would match **arrays to it.
                    np.savez_compressed(handle, allow_pickle=True, **arrays)
            path = runs_dir / f"{row['run_id']}.json"
            atomic_write_bytes(path, (json.dumps(_json_safe(row)) + "\n").encode())
        ran += len(rows)
        bar.update(len(rows))

    with bar:
        if todo:
            with open_executor(workers, scheduler) as (executor, slots):
                futures: dict[Future[list[dict[str, Any]]], int] = {
                    executor.submit(task.run_chunk, chunk): len(chunk)
                    for chunk in make_chunks(task, todo, slots, batch)
                }
                try:
                    for future in as_completed(futures):
                        rows = future.result()
                        save(rows)
                        if on_chunk is not None:
                            on_chunk(rows)
                except BaseException:
                    for future in futures:
                        future.cancel()
                    raise
    rows = [json.loads((runs_dir / f"{s.run_id}.json").read_text()) for s in specs]
    files = write_tables(out, rows, keys, trials, command)
    return StudyOutcome(rows, ran, len(specs) - len(todo), files)


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return {k: _json_safe(v) for k, v in value.items()} if isinstance(value, dict) else value


def load_curves(out: Path, run_id: str) -> dict[str, np.ndarray]:
    """Return the per-trial curves saved for a run (empty if the task gives none)."""
    path = out / RUNS_DIR / f"{run_id}.npz"
    if not path.exists():
        return {}
    with np.load(path, allow_pickle=False) as archive:
        return {k: archive[k] for k in archive.files}
