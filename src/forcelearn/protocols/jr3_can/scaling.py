"""Raw 16-bit counts <-> physical units, and the wire units of cut-off and period.

JR3 scaling: 16384 counts = full scale of the axis. Forces: full scale in N,
``F = raw * FS / 16384``. Moments: the adapter reports full scales in dN*m, so
``M = raw * FS_dNm / (16384 * 10)``; this module keeps moment full scales in
N*m (``FS_dNm / 10``) so that one formula serves all six axes.

Each side of the wire converts here and only here: the driver with
:func:`counts_to_wrench`, the emulator with :func:`counts_per_unit` and
:func:`to_count` (per axis, in floats: its hot path) or :func:`wrench_to_counts`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

# Re-exported (explicitly, `X as X`): the check lives in the core.
from forcelearn.devices import (
    FORCE_FULL_SCALE_RANGE_N as FORCE_FULL_SCALE_RANGE_N,
)
from forcelearn.devices import (
    MOMENT_FULL_SCALE_RANGE_NM as MOMENT_FULL_SCALE_RANGE_NM,
)
from forcelearn.devices import (
    check_full_scales as check_full_scales,
)

COUNTS_PER_FULL_SCALE = 16384
NEAR_SATURATION_COUNTS = 26214
"""The JR3 DSP's "near saturation" level, about 1.6 x full scale."""
INT16_MIN, INT16_MAX = -32768, 32767
DNM_PER_NM = 10.0
def full_scales_from_wire(
    forces_n: tuple[int, int, int], moments_dnm: tuple[int, int, int]
) -> np.ndarray:
    """Return the six full scales (N, N, N, N*m, N*m, N*m) from the adapter's ACK values.

    Raises:
        ValueError: a value is outside the plausible ranges (see :func:`check_full_scales`).
    """
    return check_full_scales([*forces_n, *(m / DNM_PER_NM for m in moments_dnm)])


def full_scales_to_wire(
    full_scales: np.ndarray,
) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    """Return the adapter's (forces N, moments dN*m) uint16 values for six full scales."""
    fs = np.asarray(full_scales, dtype=float)
    forces = tuple(round(float(v)) for v in fs[:3])
    moments = tuple(round(float(v) * DNM_PER_NM) for v in fs[3:])
    return forces, moments  # type: ignore[return-value]


def counts_to_wrench(raw: Sequence[int] | np.ndarray, full_scales: np.ndarray) -> np.ndarray:
    """Return (Fx..Mz) in N and N*m from six raw counts and six full scales."""
    wrench: np.ndarray = np.asarray(raw, dtype=float) * units_per_count(full_scales)
    return wrench


def units_per_count(full_scales: Sequence[float] | np.ndarray) -> np.ndarray:
    """Return the N (forces) and N*m (moments) per count of six full scales, (6,).

    ``counts * units_per_count(fs)`` is :func:`counts_to_wrench`; a receiver that
    scales every sample keeps this array for as long as the full scales hold.
    """
    scale: np.ndarray = np.asarray(full_scales, dtype=float) / COUNTS_PER_FULL_SCALE
    return scale


def counts_per_unit(full_scales: Sequence[float] | np.ndarray) -> list[float]:
    """Return the counts per N (forces) and per N*m (moments) of six full scales."""
    return [COUNTS_PER_FULL_SCALE / float(fs) for fs in full_scales]


def to_count(counts: float) -> int:
    """Return a reading in counts as the adapter sends it: rounded half to even, int16-clipped."""
    if counts >= INT16_MAX:
        return INT16_MAX
    if counts <= INT16_MIN:
        return INT16_MIN
    return round(counts)


def wrench_to_counts(wrench: Sequence[float] | np.ndarray, full_scales: np.ndarray
                     ) -> np.ndarray:
    """Return six int16 counts (rounded, clipped to the int16 range) for a wrench."""
    per_unit = counts_per_unit(full_scales)
    return np.array([to_count(float(value) * scale)
                     for value, scale in zip(wrench, per_unit, strict=True)], dtype=np.int64)


def cutoff_to_wire(cutoff_hz: float) -> int:
    """Return a cut-off in Hz as the adapter's uint16 in 0.01 Hz (0.01..655.35 Hz; 0: unfiltered).

    The adapter takes 0 as "no low-pass" (the raw decoupled data at the sensor's rate).
    """
    value = round(cutoff_hz * 100) if math.isfinite(cutoff_hz) else -1
    if cutoff_hz == 0:
        return 0
    if not 1 <= value <= 0xFFFF:
        raise ValueError(
            f"cutoff_hz={cutoff_hz} is outside 0.01..655.35 Hz (0 asks for unfiltered data)"
        )
    return value


def cutoff_from_wire(cutoff_centi_hz: int) -> float:
    """Return the adapter's cut-off (0.01 Hz units) in Hz."""
    return cutoff_centi_hz / 100.0
