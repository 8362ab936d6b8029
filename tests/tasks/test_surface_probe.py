"""The surface probe: the pure fit and map choice, and the probe against the emulator's truth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import stiffness_n_per_mm, surface_y_mm
from forcelearn.tasks.surface import SurfaceTaskSpec
from forcelearn.tasks.surface_probe import (
    ContactFit,
    ProbeError,
    ProbeResult,
    ProbeSpec,
    SurfaceProbe,
    choose_output_map,
    fit_contact,
)
from forcelearn.tools.cell_config import SafetyLimits, load_cell_config
from forcelearn.tools.cell_session import CellSession


def test_fit_recovers_a_known_line_with_its_uncertainty() -> None:
    """Fit recovers a known line with its uncertainty."""
    rng = np.random.default_rng(0)
    y = np.linspace(1.0, -9.0, 8)
    force = 2.5 * (1.5 - y) + rng.normal(0, 0.1, y.size)
    fit = fit_contact(y, force, z_mm=-10.0)
    assert fit.stiffness_n_per_mm == pytest.approx(2.5, abs=3 * fit.stiffness_std)
    assert fit.contact_y_mm == pytest.approx(1.5, abs=3 * fit.contact_y_std)
    assert 0 < fit.stiffness_std < 0.1 and 0 < fit.contact_y_std < 0.2


def test_fit_refuses_a_force_that_does_not_rise_with_depth() -> None:
    """Fit refuses a force that does not rise with depth."""
    with pytest.raises(ProbeError, match="axis/sign"):
        fit_contact(np.array([0.0, -1.0, -2.0]), np.array([3.0, 2.0, 1.0]))


def _result(k: float, y_c: float = 1.0) -> ProbeResult:
    fit = ContactFit(0.0, k, 0.01, y_c, 0.05, 0.1, 6)
    return ProbeResult(rows=[], fits=[fit], baselines_n=[0.0])


def test_the_map_puts_the_desired_force_well_inside_the_range() -> None:
    """The map puts the desired force well inside the range."""
    for k in (1.0, 2.0, 4.0):
        for force in (4.9, 19.6, 29.4):
            task = SurfaceTaskSpec(desired_force_n=force)
            choice = choose_output_map(_result(k), task, ProbeSpec(), -60.0)
            assert choice.centre_y_mm == pytest.approx(1.0 - force / k)
            deepest_allowed = 1.0 - ProbeSpec().max_depth_mm
            wanted = 3.0 + 0.5 * force / k
            assert choice.max_offset_mm == pytest.approx(
                min(wanted, choice.centre_y_mm - deepest_allowed)
            )
            assert choice.max_offset_mm >= 3.0
            # one action unit is the same force on every sponge: 0.4 x the tolerance
            assert choice.scale_mm * k == pytest.approx(0.4 * 0.5 * force)
            assert choice.centre_y_mm + choice.max_offset_mm < task.retract_y_mm


def test_configured_keys_win_over_the_probe() -> None:
    """Configured keys win over the probe."""
    task = SurfaceTaskSpec(output_scale_mm=3.0, max_offset_mm=7.0)
    choice = choose_output_map(_result(2.0), task, ProbeSpec(), -60.0)
    assert (choice.scale_mm, choice.max_offset_mm, choice.source) == (3.0, 7.0, "probe+config")
    assert choice.centre_y_mm == pytest.approx(1.0 - task.desired_force_n / 2.0)


def test_an_unreachable_force_is_refused_with_the_figures() -> None:
    """An unreachable force is refused with the figures."""
    task = SurfaceTaskSpec(desired_force_n=50.0)
    with pytest.raises(ProbeError, match=r"needs 100\.0 mm .* more than the 38\.0 mm allowed"):
        choose_output_map(_result(0.5), task, ProbeSpec(), -60.0)


@pytest.mark.parametrize("seed", range(5))
def test_the_probe_finds_the_emulators_surface_and_never_passes_the_limit(seed: int) -> None:
    """The fit matches the emulator's truth (k 10 %, contact 1 mm) under a tight 25 N limit.

    The sponge (the emulator's own force) never pushes harder than the limit.
    """
    config = load_cell_config()
    config = replace(config, safety=replace(config.safety, max_force_n=25.0))
    with CellSession(config, seed=seed) as session:
        assert session.cell is not None and session.sponge is not None
        sponge = session.sponge
        peak = [0.0]
        original = sponge.contact_force_world_n

        def recorded(position_mm: np.ndarray) -> np.ndarray:
            force = original(position_mm)
            peak[0] = max(peak[0], float(np.linalg.norm(force)))
            return force

        sponge.contact_force_world_n = recorded  # type: ignore[method-assign]
        passes: list[int] = []
        probe = SurfaceProbe(
            session.cell, config.task, ProbeSpec(), config.safety.max_step_mm, -60.0
        )
        original_point = probe._probe_point

        def point(index: int, x: float, z: float) -> None:
            passes.append(sponge.passes)
            original_point(index, x, z)

        probe._probe_point = point  # type: ignore[method-assign]
        result = probe.run()
    assert peak[0] > 5.0, "the probe did not press"
    assert peak[0] < config.safety.max_force_n
    params = config.emulator.sponge
    for fit, n in zip(result.fits, passes, strict=True):
        true_k = stiffness_n_per_mm(params, n, fit.z_mm)
        true_y = surface_y_mm(params, n, fit.z_mm)
        assert fit.stiffness_n_per_mm == pytest.approx(true_k, rel=0.10)
        assert fit.contact_y_mm == pytest.approx(true_y, abs=1.0)


def test_no_surface_in_reach_is_a_probe_error() -> None:
    """No surface in reach is a probe error."""
    config = load_cell_config()
    sponge = replace(config.emulator.sponge, surface_y_mm=-200.0)
    config = replace(config, emulator=replace(config.emulator, sponge=sponge))
    with CellSession(config, seed=0) as session:
        assert session.cell is not None
        probe = SurfaceProbe(
            session.cell, config.task, ProbeSpec(points=(0.0,)), 10.0, -60.0
        )
        with pytest.raises(ProbeError, match="no contact between"):
            probe.run()


def test_safety_defaults_leave_room_for_the_probe() -> None:
    """Safety defaults leave room for the probe."""
    assert 0.7 * SafetyLimits().max_force_n > 1.25 * SurfaceTaskSpec().desired_force_n
