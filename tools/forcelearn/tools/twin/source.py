"""Read what the twin needs from run directories: the records and the run's cell config.

The records come from the run's ``records.mcap`` through the project's reader
(:func:`forcelearn.tools.experiments.records.read_records`); a damaged file
is the reader's typed error (:class:`~forcelearn.errors.RecordsFileError`),
and a run without records is a :class:`RecordsError` that says how to make them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from forcelearn.config import read_toml
from forcelearn.errors import ForcelearnError
from forcelearn.records import StepRecord, TareRecord, TrialRecords
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.tools.experiments.fault_recovery import VOIDED_FILE
from forcelearn.tools.experiments.records import read_records, step_from_json
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
        return with_voided_moves(list(read_records(run_dir, probe=True)),
                                 voided_moves(run_dir / VOIDED_FILE))
    except ForcelearnError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RecordsError(
            f"the records of {run_dir} cannot be read ({exc}); the file is damaged: "
            "leave this run directory out of the fit"
        ) from exc


def voided_moves(path: Path) -> list[StepRecord]:
    """The moves of the trials (and probes) a run rolled back after a fault, without their bursts.

    A voided trial's readings are never used (a sensor fault may lie in them), but its
    moves happened: the tool pressed the foam, and the retract that ended the trial, in the
    trial run again, completed the pass (the sponge wears by it) and set the relaxation's
    history. Without them the twin's pass count was one short from the fault on: hidden cell
    02 of seed 6 (a foam softening over 31 passes; a false bias-step alarm voided trial 0
    after it had pressed to 33 N) cost 2,300 at the truth against 1,675 at the fit, 1,733
    with the pass, and the softening came out -4.3 sigma. Empty when the file is absent.
    """
    if not path.exists():
        return []
    steps: list[StepRecord] = []
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            if line.strip():
                steps.extend(replace(step_from_json(s), burst=None)
                             for s in json.loads(line)["steps"])
    return steps


def with_voided_moves(records: list[TrialRecords], voided: list[StepRecord]
                      ) -> list[TrialRecords]:
    """``records`` with each voided move in the first recorded trial at or after its own.

    That is the trial run again after the fault (or the next, when the run went on past
    it), its moves in time order; moves after the last recorded trial shape no reading and
    are left out.
    """
    if not voided:
        return records
    ordered = sorted(records, key=lambda t: t.trial)
    extra: dict[int, list[StepRecord]] = {}
    for step in voided:
        host = next((t.trial for t in ordered if t.trial >= step.trial), None)
        if host is not None:
            extra.setdefault(host, []).append(replace(step, trial=host))
    return [TrialRecords(t.trial, sorted(extra.get(t.trial, []) + list(t.steps),
                                         key=lambda s: s.move.start_s), t.tares)
            if t.trial in extra else t for t in ordered]


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
