"""``Pose.of`` (the emulated arm's and the EGM ramp's hot path) is the constructor."""

from __future__ import annotations

import dataclasses

import pytest

from forcelearn.devices import Pose


def test_of_is_the_constructor() -> None:
    """The object ``__init__`` builds: the same fields (objects), equality, hash, repr, frozen."""
    assert [f.name for f in dataclasses.fields(Pose)] == ["x_mm", "y_mm", "z_mm", "quaternion"]
    for args in ((900.0, -0.0, 600.0, (0.0, 1.0, 0.0, 0.0)),
                 (1.5, 2.5e-9, -3.0, (0.7071067811865476, 0.0, 0.7071067811865475, 0.0))):
        fast, slow = Pose.of(*args), Pose(*args)
        assert type(fast) is Pose and list(vars(fast)) == list(vars(slow))
        for f in dataclasses.fields(Pose):
            assert getattr(fast, f.name) is getattr(slow, f.name), f.name
        assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
        with pytest.raises(dataclasses.FrozenInstanceError):
            fast.x_mm = 1.0  # type: ignore[misc]  # frozen as the constructor's
