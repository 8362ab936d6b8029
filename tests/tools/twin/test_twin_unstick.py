"""A member's fit that stopped in a local minimum is found and refitted (hidden cell 4 of seed 1).

The linear member ended at a cost of 134,000 where the nonlinear one (exponent 0.9965 +-
0.0099, no stiffening) fitted 7,482, and the cell was reported not represented: holding a
wear's time constant at the base value restarted the refit at the amplitude fitted at the
long time constant (a far steeper wear), and the refit wandered off.
"""

from __future__ import annotations

import dataclasses

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import fit as fitting
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import LINEAR_MEMBERS
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run

READING = Reading.of(DOWN, 1, -1.0)
ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
       "lag_s": 0.03}
CELL = SpongeParams(relaxation_ratio=0.0, softening=0.2, softening_passes=60.0, set_mm=1.0,
                    set_passes=40.0)


def _values(sponge: SpongeParams) -> dict[str, float]:
    return {k: float(v) for k, v in dataclasses.asdict(sponge).items()}


def test_a_held_wear_time_restarts_its_amplitude_at_the_same_initial_rate() -> None:
    """Softening 0.95 over 425 passes held at 150: the refit starts at 0.95 x 150 / 425.

    The wear's initial rate per pass (what a run short of its time constant shows) is kept;
    a relaxation's ratio (not a wear) is not rescaled by its held time.
    """
    values = {**_values(SpongeParams()), "softening": 0.95, "softening_passes": 425.0,
              "relaxation_ratio": 0.3, "relaxation_time_s": 2.0}
    base = _values(SpongeParams())
    held = fitting._held_at_base(values, base, ["softening_passes", "relaxation_time_s"])
    assert held["softening_passes"] == base["softening_passes"]
    assert held["softening"] == 0.95 * base["softening_passes"] / 425.0
    assert held["relaxation_ratio"] == 0.3
    assert held["relaxation_time_s"] == base["relaxation_time_s"]


def test_a_member_stuck_above_a_richer_members_solution_is_refitted() -> None:
    """The simpler member's fit ended far from its best; the richer one's solution shows it.

    Refitted from that solution (the richer member's mechanism off), its cost falls to the
    richer member's; a member that is not stuck is left as it was.
    """
    records = simulate_run(SimulatedRun(trials=6, steps=8, sponge=CELL), seed=1)
    data = to_arrays(records)
    train, heldout = data.rows(list(range(5))), data.rows([5])
    truth = _values(CELL)
    elastic, linear = LINEAR_MEMBERS[0], LINEAR_MEMBERS[1]
    good = fitting.fit_member(elastic, train, heldout, truth, truth, ARM, READING, 0.05)
    richer = fitting.fit_member(linear, train, heldout, truth, truth, ARM, READING, 0.05)
    off = {**truth, "stiffness_n_per_mm": 2.0 * CELL.stiffness_n_per_mm}
    stuck = dataclasses.replace(good, values=off, train_cost=1e3 * good.train_cost + 1.0)
    fits = fitting.unstick([stuck, richer], train, heldout, truth, truth, ARM, READING, 0.05)
    assert fits[0] is not stuck
    assert fits[0].train_cost <= richer.train_cost * 1.01 + 1e-9
    assert "refitted from there" in fits[0].note
    kept = fitting.unstick([good, richer], train, heldout, truth, truth, ARM, READING, 0.05)
    assert kept[0] is good
