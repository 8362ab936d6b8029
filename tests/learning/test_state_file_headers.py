"""A damaged ``.npy`` header inside the learner's ``.npz`` is a StateFileError, always.

What a hostile review found: a header numpy had to re-tokenize raised ``tokenize.TokenError``
out of ``load_learner``. numpy's header parser (``numpy.lib.format``) also reaches
``IndentationError``, ``IndexError``, ``OverflowError`` and ``RecursionError``.
"""

from __future__ import annotations

import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

from forcelearn.errors import StateFileError
from forcelearn.learning import (
    BoxGrid,
    Dimension,
    SRVLearner,
    SRVParams,
    load_learner,
    save_learner,
)

GOOD_HEADER = "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 3, 2), }"


def npy_v1(header: str, payload: bytes = b"") -> bytes:
    """An ``.npy`` member of format 1.0 whose header text is ``header``."""
    text = header.encode("latin1") + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text + payload


def saved_with(tmp_path: Path, member: str, data: bytes) -> Path:
    """A saved learner whose ``member`` of the archive is replaced by ``data``."""
    grid = BoxGrid([Dimension("a", 0.0, 1.0, 4), Dimension("b", -1.0, 1.0, 3)])
    good = tmp_path / "good.npz"
    save_learner(SRVLearner(grid, 2, SRVParams(), rng=1), good)
    damaged = tmp_path / "damaged.npz"
    with zipfile.ZipFile(good) as src, zipfile.ZipFile(damaged, "w") as dst:
        names = src.namelist()
        assert member in names
        for name in names:
            dst.writestr(name, data if name == member else src.read(name))
    return damaged


@pytest.mark.parametrize(
    "header",
    [
        "{'descr': '<f8', 'fortran_order': False, 'shape': (4,",  # tokenize.TokenError
        "'''",  # tokenize.TokenError (EOF in a multi-line string)
        "x\n    y\n  z",  # IndentationError from the re-tokenizing
        "{'descr': (), 'fortran_order': False, 'shape': (4,)}",  # IndexError
        "{'descr': '<f8', 'fortran_order': False, 'shape': (2**80,)}",  # not a literal
        "{'descr': '<f8', 'fortran_order': False, 'shape': (" + "9" * 30 + ",)}",  # Overflow
        "{'descr': " + "(" * 400 + "'<f8', 1" + "), 1" * 399 + "), 'fortran_order': False, "
        "'shape': (1,)}",  # deep nesting
        "{'descr': '<f8', 'fortran_order': False, 'shape': (-5,)}",
        "{'descr': '\u00ff\u00fe', 'fortran_order': False, 'shape': (4, 3, 2)}",
    ],
)
def test_damaged_npy_header_inside_the_npz_is_a_state_file_error(tmp_path: Path,
                                                                 header: str) -> None:
    """Each header damage gives StateFileError naming the file, never numpy's own error."""
    path = saved_with(tmp_path, "weights.npy", npy_v1(header, bytes(8 * 24)))
    with pytest.raises(StateFileError, match=r"damaged\.npz"):
        load_learner(path)


def test_the_rebuilt_archive_itself_loads(tmp_path: Path) -> None:
    """The test's rewriting is sound: a good header in the same place loads."""
    grid = BoxGrid([Dimension("a", 0.0, 1.0, 4), Dimension("b", -1.0, 1.0, 3)])
    weights = SRVLearner(grid, 2, SRVParams(), rng=1).weights
    header = GOOD_HEADER.replace("(4, 3, 2)", str(weights.shape))
    path = saved_with(tmp_path, "weights.npy", npy_v1(header, weights.astype("<f8").tobytes()))
    learner, _ = load_learner(path)
    assert np.array_equal(learner.weights, weights)


@pytest.mark.parametrize(("old", "new"), [(b"'<f8'", b"'<f4'"), (b"'<f8'", b"'<f2'")])
def test_a_header_damaged_on_disk_is_refused_not_half_read(tmp_path: Path, old: bytes,
                                                           new: bytes) -> None:
    """One byte of a header changed on disk ("<f8" to "<f4"), CRC not redone: refused.

    Found by the state fuzz target: numpy reads only the bytes a header announces, so
    zipfile never reached the end of a member over 4 kB and never checked its CRC; the
    damaged predictions loaded as other numbers.
    """
    grid = BoxGrid([Dimension("a", 0.0, 1.0, 40), Dimension("b", -1.0, 1.0, 30)])
    good = tmp_path / "good.npz"
    save_learner(SRVLearner(grid, 2, SRVParams(), rng=1), good)
    data = good.read_bytes()
    at = data.index(b"predictions.npy")
    at = data.index(old, at)  # the member's .npy header (np.savez stores members as they are)
    damaged = tmp_path / "damaged.npz"
    damaged.write_bytes(data[:at] + new + data[at + len(old):])
    with pytest.raises(StateFileError, match=r"damaged\.npz"):
        load_learner(damaged)
