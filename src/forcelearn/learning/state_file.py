"""Save and load a learner's whole state as ``.npz`` (no pickle), written atomically.

File format ``forcelearn-srv``, version 1: one ``.npz`` archive read with
``allow_pickle=False`` holding

=======================  ==========================================================
key                      content
=======================  ==========================================================
format, format_version   ``"forcelearn-srv"``, 1
grid_names               input dimension names (str array)
grid_lows, grid_highs    range of each dimension (float64)
grid_parts               number of parts of each dimension (int64)
grid_out_of_range        ``"error"`` or ``"clamp"``
weights                  W, shape (*grid, n_outputs): μ per box and output
predictions              V, shape (*grid): r̂ per box
phase                    0 generalized, 1 specialized
consecutive_successes    the global criterion's running count
trials                   trials ended so far
switch_trial             trial of the phase switch, −1 if none yet
params_json              the :class:`SRVParams` as JSON
rng_json                 the generator's bit-generator state as JSON
metadata_json            caller's metadata (run id, trainer state...) as JSON
extra_<name>             caller's arrays saved alongside (optional; e.g. run history)
=======================  ==========================================================

The output map is code, not state: pass it again to :func:`load_learner`.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping
from typing import Any

import numpy as np

from forcelearn.atomic import atomic_writer
from forcelearn.errors import StateFileError
from forcelearn.learning.boxes import BoxGrid, Dimension
from forcelearn.learning.exploration import OutputMap
from forcelearn.learning.params import SRVParams
from forcelearn.learning.phase import Phase, PhaseSchedule
from forcelearn.learning.srv import SRVLearner

FORMAT = "forcelearn-srv"
FORMAT_VERSION = 1


def save_learner(
    learner: SRVLearner,
    path: str | os.PathLike[str],
    metadata: Mapping[str, Any] | None = None,
    arrays: Mapping[str, np.ndarray] | None = None,
) -> None:
    """Write the learner's whole state to ``path`` atomically (temp file, then rename).

    ``arrays`` (numeric or string arrays, no objects) are stored beside it as
    ``extra_<name>``; read them back with :func:`load_extra_arrays`.
    """
    grid = learner.grid
    schedule = learner.schedule
    content: dict[str, np.ndarray] = {
        "format": np.array(FORMAT),
        "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
        "grid_names": np.array([d.name for d in grid.dimensions]),
        "grid_lows": np.array([d.low for d in grid.dimensions], dtype=float),
        "grid_highs": np.array([d.high for d in grid.dimensions], dtype=float),
        "grid_parts": np.array(grid.shape, dtype=np.int64),
        "grid_out_of_range": np.array(grid.out_of_range),
        "weights": learner.weights,
        "predictions": learner.predictions,
        "phase": np.array(int(schedule.phase), dtype=np.int64),
        "consecutive_successes": np.array(schedule.consecutive_successes, dtype=np.int64),
        "trials": np.array(schedule.trials, dtype=np.int64),
        "switch_trial": np.array(
            -1 if schedule.switch_trial is None else schedule.switch_trial, dtype=np.int64
        ),
        "params_json": np.array(json.dumps(learner.params.to_dict())),
        "rng_json": np.array(json.dumps(learner.rng.bit_generator.state)),
        "metadata_json": np.array(json.dumps(dict(metadata or {}))),
    }
    for name, values in (arrays or {}).items():
        content[f"extra_{name}"] = np.asarray(values)
    with atomic_writer(path) as handle:
        np.savez(handle, **content)


def load_learner(
    path: str | os.PathLike[str], output: OutputMap | None = None
) -> tuple[SRVLearner, dict[str, Any]]:
    """Read a learner saved by :func:`save_learner`; returns it and the saved metadata.

    Raises:
        StateFileError: the file is missing, damaged, not a learner state, or of
            another format version.
    """
    try:
        with np.load(path, allow_pickle=False) as archive:
            data = {key: archive[key] for key in archive.files}
    except FileNotFoundError as exc:
        raise StateFileError(f"no learner state at {os.fspath(path)!r}") from exc
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise StateFileError(
            f"{os.fspath(path)!r} is not a readable learner state ({exc}); "
            "restore it from a backup or start a new run"
        ) from exc
    try:
        return _learner_from_arrays(data, output)
    except (KeyError, ValueError, TypeError, json.JSONDecodeError) as exc:
        if isinstance(exc, StateFileError):
            raise
        raise StateFileError(
            f"{os.fspath(path)!r} is damaged: {type(exc).__name__}: {exc}; "
            "restore it from a backup or start a new run"
        ) from exc


def load_extra_arrays(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Return the ``arrays`` saved with :func:`save_learner` (without their prefix)."""
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {k[len("extra_"):]: archive[k] for k in archive.files if k.startswith("extra_")}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise StateFileError(
            f"{os.fspath(path)!r} is not a readable learner state ({exc})"
        ) from exc


def _learner_from_arrays(
    data: dict[str, np.ndarray], output: OutputMap | None
) -> tuple[SRVLearner, dict[str, Any]]:
    if str(data.get("format", "")) != FORMAT:
        raise StateFileError("not a forcelearn learner state (its 'format' key is missing)")
    version = int(data["format_version"])
    if version != FORMAT_VERSION:
        raise StateFileError(
            f"learner state has format version {version}; this forcelearn reads version "
            f"{FORMAT_VERSION}: use the forcelearn release that wrote it"
        )
    dims = [
        Dimension(str(n), float(lo), float(hi), int(p))
        for n, lo, hi, p in zip(
            data["grid_names"],
            data["grid_lows"],
            data["grid_highs"],
            data["grid_parts"],
            strict=True,
        )
    ]
    grid = BoxGrid(dims, out_of_range=str(data["grid_out_of_range"]))  # type: ignore[arg-type]
    params = SRVParams.from_dict(json.loads(str(data["params_json"])))
    weights = np.asarray(data["weights"], dtype=float)
    predictions = np.asarray(data["predictions"], dtype=float)
    if predictions.shape != grid.shape or weights.shape[:-1] != grid.shape:
        raise StateFileError(
            f"weights {weights.shape} / predictions {predictions.shape} do not fit the grid "
            f"{grid.shape}"
        )
    rng_state = json.loads(str(data["rng_json"]))
    bit_generator = getattr(np.random, rng_state["bit_generator"])()
    bit_generator.state = rng_state
    learner = SRVLearner(
        grid, weights.shape[-1], params, np.random.Generator(bit_generator), output
    )
    learner.weights[...] = weights
    learner.predictions[...] = predictions
    switch = int(data["switch_trial"])
    learner.schedule = PhaseSchedule(
        success_trials=params.success_trials,
        phase=Phase(int(data["phase"])),
        consecutive_successes=int(data["consecutive_successes"]),
        trials=int(data["trials"]),
        switch_trial=None if switch < 0 else switch,
    )
    return learner, json.loads(str(data["metadata_json"]))
