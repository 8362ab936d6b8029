"""Read what the twin needs from run directories: the records and the run's cell config.

The records come from the run's ``records.mcap`` through the project's reader
(:func:`forcelearn.tools.experiments.records.read_records`); a damaged file
is the reader's typed error (:class:`~forcelearn.errors.RecordsFileError`),
and a run without records is a :class:`RecordsError` that says how to make them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from forcelearn.config import read_toml
from forcelearn.errors import ForcelearnError
from forcelearn.records import StepRecord, TareRecord, TrialRecords
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.tools.experiments.records import read_records
from forcelearn.tools.twin.arrays import RecordsError

CONFIG_COPY = "config.toml"


@dataclass(frozen=True)
class RunSource:
    """The records of one or more run directories, in order, and the first run's config."""

    records: list[TrialRecords]
    config: CellConfig
    raw_config: dict[str, Any]
    """The first run's config.toml as read (empty: the run used the defaults)."""
    run_dirs: list[Path]


def read_run_records(run_dir: Path) -> list[TrialRecords]:
    """The trials a run directory recorded, the surface probe's first (typed errors).

    The probe presses at several depths at one place: without it, a run that holds its
    force in band barely moves in depth, and stiffness trades off against the contact
    position (on hidden cells 04, 05, 09 both were undetermined and 40-60 % off; with
    the probe both are determined, within 1.4 % and 0.5 mm).
    """
    if not run_dir.is_dir():
        raise RecordsError(f"{run_dir} is not a run directory (forcelearn run --out DIR)")
    try:
        return list(read_records(run_dir, probe=True))
    except ForcelearnError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RecordsError(
            f"the records of {run_dir} cannot be read ({exc}); the file is damaged: "
            "leave this run directory out of the fit"
        ) from exc


def _renumbered(records: list[TrialRecords], offset: int) -> list[TrialRecords]:
    out = []
    for trial in sorted(records, key=lambda t: t.trial):
        number = trial.trial + offset
        steps: list[StepRecord] = [replace(s, trial=number) for s in trial.steps]
        tares: list[TareRecord] = [replace(t, trial=number) for t in trial.tares]
        out.append(TrialRecords(number, steps, tares))
    return out


def read_runs(run_dirs: list[Path]) -> RunSource:
    """Read run directories of one cell, taken as done one after the other (wear goes on)."""
    if not run_dirs:
        raise RecordsError("name at least one run directory")
    records: list[TrialRecords] = []
    for run_dir in run_dirs:
        trials = read_run_records(run_dir)
        offset = max((t.trial for t in records), default=0)
        records.extend(_renumbered(trials, offset))
    config_path = run_dirs[0] / CONFIG_COPY
    if config_path.exists():
        return RunSource(records, load_cell_config(config_path), read_toml(config_path),
                         list(run_dirs))
    return RunSource(records, load_cell_config(None), {}, list(run_dirs))
