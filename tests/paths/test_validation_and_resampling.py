"""The refusals before any move, and resampling to n points per pass."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from forcelearn.errors import PathRefused
from forcelearn.paths import PathLimits, TaughtPath, resample_path, validate_path
from forcelearn.paths.validation import step_lengths_mm, turn_angles_deg

LIMITS = PathLimits((-500.0, -500.0, 0.0), (500.0, 500.0, 800.0), max_step_mm=20.0,
                    max_turn_deg=10.0)


def _arc(points: int, turn_deg: float, radius_mm: float = 200.0) -> TaughtPath:
    """An arc about y through the top of a cylinder, the tool turning with the normal."""
    angles = np.radians(np.linspace(-turn_deg / 2, turn_deg / 2, points))
    positions = np.column_stack([radius_mm * np.sin(angles), np.zeros(points),
                                 radius_mm * np.cos(angles) + 100.0])
    turns = Rotation.from_euler("y", angles[:, None])
    xyzw = turns.as_quat()
    names = tuple(f"p{i + 1}" for i in range(points))
    return TaughtPath(positions, xyzw[:, [3, 0, 1, 2]], names, tuple(range(11, 11 + points)))


def _with(path: TaughtPath, index: int, position: list[float] | None = None,
          quaternion: list[float] | None = None) -> TaughtPath:
    positions, quaternions = path.positions_mm.copy(), path.quaternions_wxyz.copy()
    if position is not None:
        positions[index] = position
    if quaternion is not None:
        quaternions[index] = quaternion
    return TaughtPath(positions, quaternions, path.names, path.lines)


def test_a_good_path_passes() -> None:
    """An arc of 25 points turning 48 deg is within the limits."""
    validate_path(_arc(25, 48.0), LIMITS)


@pytest.mark.parametrize(("case", "index", "reason"), [
    ("non-unit quaternion", 7, "not a unit quaternion"),
    ("outside the workspace", 3, "outside the workspace"),
    ("step too long", 5, "more than max_step_mm"),
    ("orientation jump", 9, "the tool turns"),
    ("too few points", 0, "at least 2 are needed"),
])
def test_each_refusal_names_the_point_and_its_line(case: str, index: int, reason: str) -> None:
    """The first offending point is named by number, name and source line."""
    good = _arc(25, 48.0)
    bad = {
        "non-unit quaternion": lambda: _with(good, index, quaternion=[1.0, 0.0, 0.1, 0.0]),
        "outside the workspace": lambda: _with(good, index, position=[0.0, 0.0, 900.0]),
        "step too long": lambda: _with(good, index, position=list(
            good.positions_mm[index] + [0.0, 25.0, 0.0])),
        "orientation jump": lambda: _with(good, index, quaternion=list(
            Rotation.from_euler("x", 30, degrees=True).as_quat()[[3, 0, 1, 2]])),
        "too few points": lambda: TaughtPath(good.positions_mm[:1], good.quaternions_wxyz[:1],
                                             good.names[:1], good.lines[:1]),
    }[case]()
    with pytest.raises(PathRefused, match=reason) as caught:
        validate_path(bad, LIMITS)
    assert caught.value.index == index
    assert f"point {index + 1} (p{index + 1}) from line {11 + index}" in str(caught.value)


def test_the_quaternion_tolerance_is_the_stated_one() -> None:
    """|q| within the tolerance passes; just beyond it is refused."""
    tolerance = LIMITS.quaternion_tolerance
    good = _arc(5, 8.0)
    validate_path(_with(good, 2, quaternion=[1 + 0.9 * tolerance, 0, 0, 0]), LIMITS)
    with pytest.raises(PathRefused, match="not a unit quaternion"):
        validate_path(_with(good, 2, quaternion=[1 + 1.1 * tolerance, 0, 0, 0]), LIMITS)


@pytest.mark.parametrize("kwargs", [
    {"workspace_min_mm": (0, 0, 0), "workspace_max_mm": (0, 1, 1)},
    {"max_step_mm": 0.0}, {"max_turn_deg": -1.0}, {"min_points": 1},
])
def test_limits_are_checked(kwargs: dict[str, object]) -> None:
    """Limits that allow nothing are a ValueError naming the field."""
    base: dict[str, object] = {"workspace_min_mm": (0, 0, 0), "workspace_max_mm": (1, 1, 1),
                               "max_step_mm": 1.0, "max_turn_deg": 1.0}
    with pytest.raises(ValueError, match=next(iter(kwargs)).split("_mm")[0]):
        PathLimits(**{**base, **kwargs})  # type: ignore[arg-type]


@settings(max_examples=25)
@given(st.integers(3, 12), st.integers(2, 80), st.floats(5.0, 90.0))
def test_resampling_spaces_points_evenly_along_the_taught_polyline(
    taught_points: int, points: int, turn_deg: float
) -> None:
    """Same ends, equal steps along the polyline, points on it, orientations slerped."""
    path = _arc(taught_points, turn_deg)
    out = resample_path(path, points)
    assert len(out) == points
    np.testing.assert_allclose(out.positions_mm[[0, -1]], path.positions_mm[[0, -1]], atol=1e-9)
    arc = np.concatenate([[0.0], np.cumsum(step_lengths_mm(path))])
    wanted = np.linspace(0.0, arc[-1], points)
    expected = np.column_stack([np.interp(wanted, arc, path.positions_mm[:, k]) for k in range(3)])
    np.testing.assert_allclose(out.positions_mm, expected, atol=1e-6)
    slerp = Slerp(arc, Rotation.from_quat(path.quaternions_wxyz[:, [1, 2, 3, 0]]))
    got = Rotation.from_quat(out.quaternions_wxyz[:, [1, 2, 3, 0]])
    assert np.all((slerp(wanted).inv() * got).magnitude() < 1e-9)
    assert turn_angles_deg(out).sum() == pytest.approx(turn_angles_deg(path).sum(), rel=1e-6)


def test_resampling_drops_repeated_poses_and_refuses_a_turn_in_place() -> None:
    """A pose taught twice is harmless; turning without moving cannot be spread by arc length."""
    path = _arc(5, 20.0)
    twice = TaughtPath(np.repeat(path.positions_mm, 2, axis=0),
                       np.repeat(path.quaternions_wxyz, 2, axis=0))
    np.testing.assert_allclose(resample_path(twice, 9).positions_mm,
                               resample_path(path, 9).positions_mm, atol=1e-9)
    turned = _with(path, 2, position=list(path.positions_mm[1]))
    with pytest.raises(PathRefused, match=r"turns .* in place"):
        resample_path(turned, 9)
    with pytest.raises(ValueError, match="points must be >= 2"):
        resample_path(path, 1)
