"""A held parameter's ignorance is part of the fitted ones' 1-sigma."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import forward
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.held import HELD_FACTOR, held_range, held_spread
from forcelearn.tools.twin.params import LINEAR_MEMBERS, Member
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run

READING = forward.Reading.of(DOWN, 1, -1.0)
ARM = base_arm()  # the emulator's defaults
TRUTH = SpongeParams(set_mm=1.5, set_passes=4.0, relaxation_ratio=0.0)


@dataclass
class _Fit:
    member: Member
    values: dict[str, float]
    held: tuple[str, ...] = ()
    sigmas: dict[str, float] = field(default_factory=dict)


def test_a_held_wear_scale_widens_the_contact_it_trades_with() -> None:
    """The set's time constant held: the fresh surface's 1-sigma grows; nothing held: none."""
    records = simulate_run(SimulatedRun(trials=6, steps=8, sponge=TRUTH), seed=1)
    data = to_arrays(records)
    values = {k: float(v) for k, v in dataclasses.asdict(TRUTH).items()}
    member = LINEAR_MEMBERS[0]  # the linear, elastic foam: its wear fitted
    held = held_spread(_Fit(member, values, ("set_passes",), {"set_passes": math.inf}),
                       data, ARM, READING, 0.05)
    assert held["surface_y_mm"] > 0.0
    assert held_spread(_Fit(member, values), data, ARM, READING, 0.05) == {}


def test_the_held_range_is_the_last_fit_sigma_or_a_factor() -> None:
    """A loose value spans a factor either way; one known better, its 1-sigma."""
    assert held_range("set_passes", 100.0, math.inf) == (100.0 / HELD_FACTOR,
                                                         100.0 * HELD_FACTOR)
    assert held_range("set_passes", 100.0, 10.0) == (90.0, 110.0)


def test_with_an_identification_the_relaxation_time_is_never_held() -> None:
    """A loose relaxation time may be held at the base value, unless an identification measures it.

    Hidden cell 6 of seed 1: held at 0.4 s where the cell's was 0.28 s, the relaxation ratio
    came out 0.17 +- 0.02 against 0.25; fitted, 0.27 +- 0.05 and 0.27 s.
    """
    from forcelearn.tools.twin.fit import IDENTIFIED_SCALES, loose_holdable

    free = ["stiffness_n_per_mm", "relaxation_ratio", "relaxation_time_s"]
    values = {"stiffness_n_per_mm": 2.0, "relaxation_ratio": 0.25, "relaxation_time_s": 0.3}
    spread = {"stiffness_n_per_mm": 0.01, "relaxation_ratio": 0.01, "relaxation_time_s": 0.05}
    assert loose_holdable(free, values, spread) == ["relaxation_time_s"]
    assert loose_holdable(free, values, spread, IDENTIFIED_SCALES) == []
