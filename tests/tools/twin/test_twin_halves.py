"""The force halves' refits keep the surface probe's bursts in both halves.

The probe presses each point from first touch to past the task's force. Split by force
with the trials' bursts, its shallow presses all fell in the low half and the high half
(deep bursts only) extrapolated the contact from ~10 mm: on the default run of 300
trials, seed 0, the halves' contacts were 0.05 and 0.38 mm (truth 0), the contact's
sigma 0.166 mm on a cell whose law holds. The probe is what ties the contact to the
stiffness, so every refit keeps it, as the trial blocks already did.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import problem as problem_module
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import LINEAR_MEMBERS, Member
from forcelearn.tools.twin.problem import Problem, jackknife
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run

ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
       "lag_s": 0.03}


@dataclass
class _Fit:
    member: Member
    values: dict[str, float]
    held: tuple[str, ...] = ()


def test_the_probe_stays_in_both_force_halves(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every refit's mask keeps every probe burst; the halves split only the trials'."""
    run = SimulatedRun(trials=6, steps=8, probe_points=(0.2, 0.6))
    train = to_arrays(simulate_run(run, seed=1))
    probe_rows = ~(train.is_step & train.has_burst).any(axis=1)
    assert probe_rows.any() and (~probe_rows).sum() >= 4
    seen: list[list[np.ndarray]] = []

    def refits(self: Problem, names: list[str], values: dict[str, float],
               masks: list[np.ndarray], steps: list[int]) -> np.ndarray:
        seen.append([np.asarray(m) for m in masks])
        return np.repeat(np.array([[values[n] for n in names]]), len(masks), axis=0)

    monkeypatch.setattr(problem_module.Problem, "refits", refits)
    values = {k: float(v) for k, v in dataclasses.asdict(SpongeParams()).items()}
    jackknife(_Fit(LINEAR_MEMBERS[0], values), train, ARM, Reading.of(DOWN, 1, -1.0), 0.1)
    (masks,) = seen
    assert len(masks) == 6  # four blocks and two force halves
    probe_bursts = train.has_burst & probe_rows[:, None]
    pressed = probe_bursts & (train.mean_n > 0.5)
    assert pressed.any()  # the probe's presses are contact bursts
    for mask in masks:
        assert np.all(mask[probe_bursts])
    low, high = masks[4], masks[5]
    trial_contact = train.has_burst & ~probe_rows[:, None] & (train.mean_n > 0.5)
    assert np.any(~low & trial_contact) and np.any(~high & trial_contact)
    assert not np.any(~low & ~high)  # each trial burst left out of one half at most
