"""The nested rule is judged again on the members' final costs.

A member whose fit ends above its nested parent's train cost is dropped (a richer member
never fits worse than the one it contains). The walk per burst refits every member after
that; the drop is judged again on those costs.
"""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from forcelearn.tools.twin.fit import nested_rechecked
from forcelearn.tools.twin.params import LINEAR_MEMBERS, NONLINEAR_MEMBER, Member


@dataclass
class _Fit:
    member: Member
    train_cost: float
    eligible: bool = True
    note: str = ""


@pytest.mark.parametrize(("cost", "was_eligible", "eligible"), [
    (85_420.0, False, True),   # seed 11 cell 25's linear member: dropped, then below its parent
    (205_100.0, False, False),  # still above: still dropped, its note unchanged
    (86_500.0, True, False),   # a refit left an eligible member above its parent: dropped
    (86_000.0, True, True),
])
def test_a_member_is_dropped_on_its_final_cost(cost: float, was_eligible: bool,
                                               eligible: bool) -> None:
    """Against the linear-elastic parent at 86,340 (the walk's refit)."""
    fits = [_Fit(LINEAR_MEMBERS[0], 86_340.0), _Fit(LINEAR_MEMBERS[1], cost, was_eligible),
            _Fit(NONLINEAR_MEMBER, 1_842.0)]
    result = nested_rechecked(fits)  # type: ignore[arg-type]
    assert result[1].eligible is eligible
    assert result[0].eligible and result[2].eligible
    changed = eligible != was_eligible
    assert ("walk per burst" in result[1].note) is changed
