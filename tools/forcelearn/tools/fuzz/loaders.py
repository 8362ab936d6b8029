"""Mutants that reach past a loader's first checks, for the ``state`` and ``calibration`` targets.

* :func:`npz_header_mutant`: a learner state whose archive is intact (correct CRCs) but
  one member's ``.npy`` header is damaged, so numpy's header parser, not zipfile, meets
  the damage (the path by which a ``tokenize.TokenError`` once escaped the loader);
* :func:`calibration_value_mutant`: a calibration file with one to three values replaced
  by odd ones and its digest recomputed, as a hand-made file would have, so the physical
  bounds, not the digest, must refuse it.
"""

from __future__ import annotations

import contextlib
import io
import random
import struct
import zipfile
from collections.abc import Callable
from typing import Any

DAMAGED_HEADERS = (
    "{'descr': '<f8', 'fortran_order': False, 'shape': (4,",
    "'''", "x\n    y\n  z", "{'descr': (), 'fortran_order': False, 'shape': (4,)}",
    "{'descr': '<f8', 'fortran_order': False, 'shape': (" + "9" * 30 + ",)}",
    "{'descr': '<f8', 'fortran_order': False, 'shape': (-5,)}",
    "{'descr': '|O', 'fortran_order': False, 'shape': (1,)}",
    "{'descr': [('a', '<f8', (2**62,))], 'fortran_order': False, 'shape': (1,)}",
    "{'descr': '<f8', 'fortran_order': 1, 'shape': (1,)}", "{}", "[]", "None", "",
    "{'descr': " + "(" * 300 + "'<f8'" + ", 1)" * 300 + ", 'fortran_order': False, "
    "'shape': (1,)}",
    "\x00\xff", "{'descr': 'V0', 'fortran_order': False, 'shape': (10**9,)}",
)
"""Header texts that reach numpy's error paths (syntax, tokenizer, descr, shape, sizes)."""


def _split_npy(data: bytes) -> tuple[bytes, bytes, bytes] | None:
    """(preamble up to the length field, header, rest) of an ``.npy``, or None."""
    if len(data) < 10 or not data.startswith(b"\x93NUMPY"):
        return None
    size_format = "<H" if data[6] == 1 else "<I"
    at = 8 + struct.calcsize(size_format)
    (length,) = struct.unpack(size_format, data[8:at])
    return data[:8], data[at : at + length], data[at + length :]


def npz_header_mutant(rng: random.Random, good: bytes,
                      mutate: Callable[[bytes], bytes]) -> bytes:
    """``good`` (an ``.npz``) with one member's ``.npy`` header damaged, CRCs intact.

    ``mutate`` damages bytes (the fuzz harness's mutations); half the time a header of
    :data:`DAMAGED_HEADERS` replaces the real one instead. The length field is right,
    except one time in ten.
    """
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(good)) as src, zipfile.ZipFile(out, "w") as dst:
        names = src.namelist()
        victim = rng.choice(names)
        for name in names:
            data = src.read(name)
            parts = _split_npy(data) if name == victim else None
            if parts is not None:
                preamble, header, rest = parts
                if rng.random() < 0.5:
                    header = rng.choice(DAMAGED_HEADERS).encode("latin1") + b"\n"
                else:
                    header = mutate(header)
                size_format = "<H" if preamble[6] == 1 else "<I"
                length = len(header)
                if rng.random() < 0.1:
                    length = rng.randrange(1 << (16 if size_format == "<H" else 20))
                with_length = struct.pack(size_format, min(length, (1 << 16) - 1)
                                          if size_format == "<H" else length)
                data = preamble + with_length + header + rest
            dst.writestr(name, data)
    return out.getvalue()


def _leaves(table: dict[str, Any], path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    leaves: list[tuple[Any, ...]] = []
    for key, value in table.items():
        if isinstance(value, dict):
            leaves.extend(_leaves(value, (*path, key)))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for i, item in enumerate(value):
                leaves.extend(_leaves(item, (*path, key, i)))
        elif key not in ("digest", "format_version"):
            leaves.append((*path, key))
    return leaves


def calibration_value_mutant(rng: random.Random, good: bytes,
                             odd: Callable[[random.Random, object], object]) -> bytes:
    """``good`` (a calibration file) with 1 to 3 values replaced by ``odd`` ones, digest redone.

    A value TOML cannot carry in the digest's canonical form (NaN, inf) keeps the old
    digest; the finite-number check must refuse it first.
    """
    import tomllib

    import tomli_w

    from forcelearn.calibration.file_format import content_digest

    doc = tomllib.loads(good.decode("utf-8"))
    for path in rng.sample(_leaves(doc), rng.randint(1, 3)):
        table: Any = doc
        for key in path[:-1]:
            table = table[key]
        table[path[-1]] = odd(rng, table[path[-1]])
    with contextlib.suppress(ValueError, TypeError):
        doc["digest"] = content_digest(doc)
    return tomli_w.dumps(doc).encode("utf-8")
