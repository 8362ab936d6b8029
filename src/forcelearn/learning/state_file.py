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
import lzma
import os
import struct
import tokenize
import zipfile
import zlib
from collections.abc import Callable, Mapping
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
        # allow_pickle is numpy's default, named so that mypy does not match **content to it.
        np.savez(handle, allow_pickle=True, **content)


def load_learner(
    path: str | os.PathLike[str], output: OutputMap | None = None
) -> tuple[SRVLearner, dict[str, Any]]:
    """Read a learner saved by :func:`save_learner`; returns it and the saved metadata.

    Every value is checked before use: finite weights and predictions, integer
    counters in range, a known random generator, metadata that is a table.

    Raises:
        StateFileError: the file is missing, damaged, not a learner state, or of
            another format version.
    """
    data = _read_archive(path, lambda key: not key.startswith("extra_"))
    try:
        return _learner_from_arrays(data, output)
    except StateFileError as exc:  # another format or version: the advice is in the message
        raise StateFileError(f"{os.fspath(path)!r}: {exc}") from exc
    except (LookupError, ValueError, TypeError, ArithmeticError, json.JSONDecodeError) as exc:
        raise StateFileError(
            f"{os.fspath(path)!r} is damaged: {type(exc).__name__}: {_describe(exc)}; "
            "restore it from a backup or start a new run"
        ) from exc


def load_extra_arrays(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Return the ``arrays`` saved with :func:`save_learner` (without their prefix)."""
    data = _read_archive(path, lambda key: key.startswith("extra_"))
    return {key[len("extra_"):]: value for key, value in data.items()}


_ZIP_MAGIC = b"PK\x03\x04"
_READ_ERRORS = (
    OSError, ValueError, EOFError, LookupError, TypeError, ArithmeticError, MemoryError,
    NotImplementedError, RuntimeError, SyntaxError, tokenize.TokenError, struct.error,
    zipfile.BadZipFile, zlib.error, lzma.LZMAError,
)
"""What numpy and zipfile raise on a damaged archive (numpy 2.x ``lib/_format_impl.py``).

zipfile: BadZipFile, zlib.error, lzma.LZMAError, EOFError, NotImplementedError (a
compression method it lacks), RuntimeError (an "encrypted" flag), OSError, a
UnicodeDecodeError of a member name. numpy's ``.npy`` reader: ValueError for most
damage (magic, version, header text, keys, shape, dtype, short data), but its header
parser also lets through ``tokenize.TokenError`` and ``SyntaxError``/``IndentationError``
(from re-tokenizing a version 1/2 header that ``ast.literal_eval`` refused),
``IndexError`` and ``TypeError`` (a malformed ``descr``), ``RecursionError`` (a deeply
nested one), ``OverflowError`` (a shape beyond int64) and ``MemoryError`` (a shape too
large to allocate). LookupError covers IndexError and KeyError, ArithmeticError
OverflowError, RuntimeError RecursionError."""


def _read_archive(
    path: str | os.PathLike[str], wanted: Callable[[str], bool]
) -> dict[str, np.ndarray]:
    """Return the wanted arrays of the ``.npz`` at ``path``; StateFileError if unreadable."""
    where = repr(os.fspath(path))
    advice = "restore it from a backup or start a new run"
    try:
        with open(path, "rb") as handle:
            magic = handle.read(len(_ZIP_MAGIC))
    except FileNotFoundError as exc:
        raise StateFileError(f"no learner state at {where}") from exc
    except OSError as exc:
        raise StateFileError(f"cannot read the learner state {where} ({exc})") from exc
    if magic != _ZIP_MAGIC:
        kind = "a single .npy array" if magic.startswith(b"\x93NUM") else "not an .npz archive"
        raise StateFileError(f"{where} is not a learner state ({kind}); {advice}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            if not isinstance(archive, np.lib.npyio.NpzFile):
                raise StateFileError(f"{where} is not a learner state (not an .npz archive)")
            # numpy reads only the bytes a member's header announces, so zipfile never
            # reaches the member's end and never checks its CRC: a header damaged on disk
            # ("<f8" to "<f4") would load half the data as other numbers. Check every CRC,
            # and that each member holds exactly the data its header announces.
            members = archive.zip
            if members is None:  # pragma: no cover - np.load keeps the archive open here
                raise StateFileError(f"{where} is not a learner state (closed archive)")
            damaged = members.testzip()
            if damaged is not None:
                raise StateFileError(f"{where} is damaged: its member {damaged!r} fails its CRC "
                                     f"check; {advice}")
            arrays = {key: archive[key] for key in archive.files if wanted(key)}
            for key, array in arrays.items():
                _check_member_size(members, key, array, where, advice)
            return arrays
    except StateFileError:
        raise
    except _READ_ERRORS as exc:
        raise StateFileError(
            f"{where} is not a readable learner state ({type(exc).__name__}: {_describe(exc)}); "
            f"{advice}"
        ) from exc


def _check_member_size(archive: zipfile.ZipFile, key: str, array: np.ndarray, where: str,
                       advice: str) -> None:
    """Refuse a member whose data is not exactly what its ``.npy`` header announces."""
    name = f"{key}.npy" if f"{key}.npy" in archive.namelist() else key
    info = archive.getinfo(name)
    with archive.open(info) as member:
        preamble = member.read(12)
    size_format = "<H" if preamble[6:7] == b"\x01" else "<I"
    start = 8 + struct.calcsize(size_format)
    (header_length,) = struct.unpack(size_format, preamble[8:start])
    if info.file_size != start + header_length + array.nbytes:
        raise StateFileError(
            f"{where} is damaged: {key!r} holds {info.file_size - start - header_length} bytes "
            f"of data but its header announces {array.nbytes} ({array.dtype}, "
            f"{array.shape}); {advice}"
        )


def _describe(exc: BaseException) -> str:
    """The exception's text, without numpy's advice to load pickled data."""
    text = str(exc)
    if "pickle" in text:
        return "it holds pickled objects, which are never loaded"
    return text[:200]


_BIT_GENERATORS: dict[str, type[np.random.BitGenerator]] = {
    "PCG64": np.random.PCG64,
    "PCG64DXSM": np.random.PCG64DXSM,
    "MT19937": np.random.MT19937,
    "Philox": np.random.Philox,
    "SFC64": np.random.SFC64,
}
MAX_COUNT = 10**9
"""Largest trial counter accepted (far beyond any run; larger means damage)."""
MAX_BOXES = 10**7
"""Largest grid accepted, in boxes (a damaged ``grid_parts`` must not exhaust memory)."""


def _array(data: dict[str, np.ndarray], key: str, kinds: str, ndim: int | None) -> np.ndarray:
    """Return ``data[key]``, checking its dtype kind and number of dimensions."""
    value = data[key]
    if not isinstance(value, np.ndarray) or value.dtype.kind not in kinds:
        raise ValueError(f"'{key}' has type {getattr(value, 'dtype', type(value))}")
    if ndim is not None and value.ndim != ndim:
        raise ValueError(f"'{key}' has {value.ndim} dimensions, expected {ndim}")
    return value


def _count(data: dict[str, np.ndarray], key: str, low: int, high: int) -> int:
    """Return an integer scalar in ``low..high``."""
    value = int(_array(data, key, "iu", 0))
    if not low <= value <= high:
        raise ValueError(f"'{key}' is {value}, expected {low}..{high}")
    return value


def _text(data: dict[str, np.ndarray], key: str) -> str:
    return str(_array(data, key, "U", 0))


def _finite(data: dict[str, np.ndarray], key: str) -> np.ndarray:
    value = _array(data, key, "f", None)
    if not np.all(np.isfinite(value)):
        raise ValueError(f"'{key}' holds NaN or infinite values")
    return value.astype(float)


def _learner_from_arrays(
    data: dict[str, np.ndarray], output: OutputMap | None
) -> tuple[SRVLearner, dict[str, Any]]:
    if "format" not in data or _text(data, "format") != FORMAT:
        raise StateFileError("not a forcelearn learner state (its 'format' key is missing)")
    version = int(_array(data, "format_version", "iu", 0))
    if version != FORMAT_VERSION:
        raise StateFileError(
            f"learner state has format version {version}; this forcelearn reads version "
            f"{FORMAT_VERSION}: use the forcelearn release that wrote it"
        )
    names = _array(data, "grid_names", "U", 1)
    lows, highs = _finite(data, "grid_lows"), _finite(data, "grid_highs")
    parts = _array(data, "grid_parts", "iu", 1)
    if not len(names) == len(lows) == len(highs) == len(parts) >= 1:
        raise ValueError("grid_names, grid_lows, grid_highs, grid_parts differ in length")
    if np.any(parts < 1) or float(np.prod(parts.astype(float))) > MAX_BOXES:
        raise ValueError(f"grid_parts {parts.tolist()} must be >= 1, <= {MAX_BOXES} boxes")
    dims = [
        Dimension(str(n), float(lo), float(hi), int(p))
        for n, lo, hi, p in zip(names, lows, highs, parts, strict=True)
    ]
    out_of_range = _text(data, "grid_out_of_range")
    if out_of_range not in ("error", "clamp"):
        raise ValueError(f"grid_out_of_range is {out_of_range!r}, not 'error' or 'clamp'")
    grid = BoxGrid(dims, out_of_range=out_of_range)  # type: ignore[arg-type]
    params_table = json.loads(_text(data, "params_json"))
    if not isinstance(params_table, dict):
        raise ValueError("params_json is not a table")
    params = SRVParams.from_dict(params_table)
    weights, predictions = _finite(data, "weights"), _finite(data, "predictions")
    if (
        predictions.shape != grid.shape
        or weights.shape[:-1] != grid.shape
        or weights.ndim != predictions.ndim + 1
        or weights.shape[-1] < 1
    ):
        raise ValueError(
            f"weights {weights.shape} / predictions {predictions.shape} do not fit the grid "
            f"{grid.shape}"
        )
    rng = _generator(_text(data, "rng_json"))
    trials = _count(data, "trials", 0, MAX_COUNT)
    consecutive = _count(data, "consecutive_successes", 0, trials)
    switch = _count(data, "switch_trial", -1, trials - 1)
    phase = Phase(_count(data, "phase", min(Phase), max(Phase)))
    metadata = json.loads(_text(data, "metadata_json"))
    if not isinstance(metadata, dict):
        raise ValueError(f"metadata_json is a {type(metadata).__name__}, not a table")
    learner = SRVLearner(grid, weights.shape[-1], params, rng, output)
    learner.weights[...] = weights
    learner.predictions[...] = predictions
    learner.schedule = PhaseSchedule(
        success_trials=params.success_trials,
        phase=phase,
        consecutive_successes=consecutive,
        trials=trials,
        switch_trial=None if switch < 0 else switch,
    )
    return learner, metadata


def _generator(rng_json: str) -> np.random.Generator:
    """Rebuild the saved generator; only the known bit generators are ever constructed."""
    state = json.loads(rng_json)
    name = state.get("bit_generator") if isinstance(state, dict) else None
    if name not in _BIT_GENERATORS:
        raise ValueError(
            f"rng_json names bit generator {name!r}; known: {sorted(_BIT_GENERATORS)}"
        )
    bit_generator = _BIT_GENERATORS[name]()
    bit_generator.state = state
    return np.random.Generator(bit_generator)
