"""Checks every robot driver makes of a caller's target before anything is sent (pure).

A coordinate must be a finite number (a numpy scalar too; not a bool or text); a
quaternion (w, x, y, z) must be exactly four such numbers of unit norm within
``TARGET_NORM_TOLERANCE``. A bad value is :class:`~forcelearn.errors.InvalidTarget`
where it was passed, naming what was wrong.
"""

from __future__ import annotations

import math

from forcelearn.errors import InvalidTarget

TARGET_NORM_TOLERANCE = 1e-6
"""A caller's quaternion must have a norm within this of 1."""


def _as_float(value: object) -> float | None:
    """``value`` as a float (numpy scalars too), or None for a bool, text or a non-number."""
    if isinstance(value, bool | str | bytes):
        return None
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        return None


def finite_number(value: object, what: str) -> float:
    """``value`` as a finite float, else InvalidTarget naming ``what``."""
    number = _as_float(value)
    if number is None:
        raise InvalidTarget(f"{what} must be a number, got {value!r}; nothing was sent")
    if not math.isfinite(number):
        raise InvalidTarget(f"{what} must be finite, got {number}; nothing was sent")
    return number


def unit_quaternion(value: object, what: str) -> tuple[float, float, float, float]:
    """``value`` as 4 finite floats (w, x, y, z) of unit norm (within 1e-6), else InvalidTarget."""
    try:
        items = list(value)  # type: ignore[call-overload]
    except TypeError:
        raise InvalidTarget(
            f"{what} must be 4 numbers (w, x, y, z), got {value!r}; nothing was sent"
        ) from None
    if len(items) != 4:
        raise InvalidTarget(
            f"{what} must be 4 numbers (w, x, y, z), 4 finite ones of unit norm; got "
            f"{len(items)}: {items}; nothing was sent"
        )
    numbers = [_as_float(c) for c in items]
    if any(n is None for n in numbers):
        raise InvalidTarget(f"{what} must be 4 numbers (w, x, y, z), got {items}; nothing was sent")
    w, x, y, z = (n for n in numbers if n is not None)
    if not all(math.isfinite(c) for c in (w, x, y, z)):
        raise InvalidTarget(
            f"{what} must be 4 finite numbers (w, x, y, z), got {items}; nothing was sent"
        )
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not abs(norm - 1.0) <= TARGET_NORM_TOLERANCE:
        raise InvalidTarget(f"{what} must be unit length, its norm is {norm:.6f}; nothing was sent")
    return w, x, y, z
