"""A stiff part with a small force: every probe refines its approach (tasks/approach.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import stiffness_n_per_mm
from forcelearn.press_guard import MIN_STEP_MM
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.approach import (
    PROBE_APPROACH_ADVICE,
    READINGS,
    REFINES,
    ApproachTooCoarse,
    FineApproach,
)
from forcelearn.tasks.surface_probe import ProbeSpec, SurfaceProbe

TruePeak = Callable[[CellSession], list[float]]  # the true_force_peak fixture (conftest)


def test_a_first_contact_that_passes_a_third_of_the_press_asks_for_a_finer_step() -> None:
    """6 N in 1 mm against a 5.25 N press: finer; the default sponge's 2.5 N of 23.5: not."""
    stiff = FineApproach(1.0, 1.0, 5.25, PROBE_APPROACH_ADVICE)
    assert stiff.again(6.0, 0.0, 1.0)
    assert stiff.step_mm * 6.0 * READINGS <= 5.25 + 1e-9
    sponge = FineApproach(1.0, 1.0, 23.5, PROBE_APPROACH_ADVICE)
    assert not sponge.again(2.5, 0.0, 1.0)
    assert sponge.step_mm == 1.0 and sponge.stiffness_n_per_mm == 0.0


def test_fresh_approaches_are_bounded_then_say_what_to_set() -> None:
    """REFINES fresh approaches; then a contact past the deepest press's force is the error."""
    approach = FineApproach(1.0, 1.0, 5.25, PROBE_APPROACH_ADVICE)
    for _ in range(REFINES):  # each contact 2.92 N: a step 0.6 x the last
        assert approach.again(2.92, 0.0, approach.step_mm)
    assert not approach.again(2.92, 0.0, approach.step_mm)  # under 6.25 N: it presses on
    with pytest.raises(ApproachTooCoarse, match=r"set \[probe\] approach_step_mm to [0-9.]+ mm"):
        approach.again(7.0, 0.0, approach.step_mm)


def test_with_no_finer_step_left_a_contact_under_the_deepest_force_presses_on() -> None:
    """At the finest step a noisy pair (0.9 N, then 2.3 N 0.05 mm on) is no error: it presses."""
    approach = FineApproach(1.0, 1.0, 2.75, PROBE_APPROACH_ADVICE)
    approach.step_mm = MIN_STEP_MM
    assert not approach.again(2.3, 0.9, MIN_STEP_MM)
    assert approach.fine_step_mm() == MIN_STEP_MM


def _part(stiffness: float, desired: float, limit: float = 60.0) -> CellConfig:
    config = load_cell_config()
    sponge = replace(config.emulator.sponge, stiffness_n_per_mm=stiffness)
    return replace(config, emulator=replace(config.emulator, sponge=sponge),
                   task=replace(config.task, desired_force_n=desired),
                   safety=replace(config.safety, max_force_n=limit))


@pytest.mark.parametrize(("stiffness", "desired", "seed", "rel"),
                         [(15.0, 3.0, 0, 0.15), (8.0, 5.0, 0, 0.15), (8.0, 2.0, 1, 0.35)])
def test_the_surface_probe_reads_a_stiff_part_three_times_with_its_default_step(
        stiffness: float, desired: float, seed: int, rel: float,
        true_force_peak: TruePeak) -> None:
    """1 mm steps on stiff parts with small forces: each point fits READINGS readings or more.

    With the approach's own step the first contact passed the deepest press ("need 2"). With
    a refined one, on 8 N/mm at 2 N, two press readings 0.0125 mm apart read 0.12 N less (the
    noise), the press measured 1e-3 N/mm and stepped 9.9 mm in, to the force limit (here, on
    a session without the run's press guard, to 80 N). On 15 N/mm at 3 N a contact met in a
    1 mm step at z = -20 mm (no refine needed) then pressed in the 0.25 mm floor of that step:
    3.5 N in one step, two readings. The stiffness within ``rel``: 8 N/mm
    at 2 N spans 1.5 N over 0.2 mm, and its fits scatter 0.84-1.30x the truth with any step
    (0.91-1.13x with a configured 0.1 mm).
    """
    config = _part(stiffness, desired)
    spec = ProbeSpec(points=(0.0, 0.1, 0.2, 0.25, 0.5, 0.75, 0.875, 1.0))
    with CellSession(config, seed=seed) as session:
        assert session.cell is not None
        peak = true_force_peak(session)
        probe = SurfaceProbe(session.cell, config.task, spec, config.safety.max_step_mm, -60.0)
        result = probe.run()
    assert any(r["phase"] == "refine" for r in result.rows)
    params = config.emulator.sponge
    for fit in result.fits:
        assert fit.points >= READINGS
        assert fit.stiffness_n_per_mm == pytest.approx(stiffness_n_per_mm(params, 0, fit.z_mm),
                                                       rel=rel)
    assert peak[0] < spec.max_force_ratio * config.safety.max_force_n


def test_a_part_too_stiff_for_the_finest_step_ends_in_the_typed_error_off_the_part(
        true_force_peak: TruePeak) -> None:
    """30 N/mm at 1 N (a 0.25 N press): not even 0.05 mm reads it; the error says what to set."""
    config = _part(30.0, 1.0)
    with CellSession(config, seed=0) as session:
        assert session.cell is not None and session.physics is not None
        peak = true_force_peak(session)
        probe = SurfaceProbe(session.cell, config.task, ProbeSpec(points=(0.0,)),
                             config.safety.max_step_mm, -60.0)
        with pytest.raises(ApproachTooCoarse, match=r"finest step.*raise \[task\] desired_force_n"):
            probe.run()
        assert session.cell.pose.y_mm == pytest.approx(config.task.retract_y_mm)
        peak_before = peak[0]
        assert session.sponge is not None
        assert np.linalg.norm(session.sponge.contact_force_world_n(
            session.physics._position_mm)) == 0.0  # off the part
    assert 0.0 < peak_before < config.safety.max_force_n
