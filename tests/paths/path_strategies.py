"""Hypothesis strategies for taught paths."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from forcelearn.paths import Frame, TaughtPath

coordinates = st.floats(-2000.0, 2000.0, allow_nan=False, allow_infinity=False)


@st.composite
def unit_quaternions(draw: st.DrawFn) -> np.ndarray:
    """A unit quaternion (w, x, y, z) with w >= 0, from a random rotation."""
    seed = draw(st.integers(0, 2**32 - 1))
    xyzw = Rotation.random(random_state=seed).as_quat()
    wxyz = xyzw[[3, 0, 1, 2]]
    return wxyz if wxyz[0] >= 0 else -wxyz


@st.composite
def taught_paths(draw: st.DrawFn, min_size: int = 1, max_size: int = 12) -> TaughtPath:
    """A path of random poses, with or without names."""
    n = draw(st.integers(min_size, max_size))
    positions = [[draw(coordinates) for _ in range(3)] for _ in range(n)]
    quaternions = [draw(unit_quaternions()) for _ in range(n)]
    named = draw(st.booleans())
    names = tuple(f"p{10 * (i + 1)}" for i in range(n)) if named else ()
    return TaughtPath(np.array(positions), np.array(quaternions), names)


@st.composite
def frames(draw: st.DrawFn) -> Frame:
    """A random rigid frame."""
    q = draw(unit_quaternions())
    return Frame((draw(coordinates), draw(coordinates), draw(coordinates)),
                 (float(q[0]), float(q[1]), float(q[2]), float(q[3])))
