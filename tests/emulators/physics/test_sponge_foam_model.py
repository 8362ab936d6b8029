"""The sponge's model family: nonlinear law, hysteresis, friction; each off by default."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import (
    Sponge,
    SpongeParams,
    contact_force_n,
    stiffness_n_per_mm,
    surface_normal,
    surface_y_mm,
)

Z = -40.0


def _at(y: float, z: float = Z) -> np.ndarray:
    return np.array([900.0, y, z])


def _linear_law(p: SpongeParams, passes: float, pos: np.ndarray, relaxing_mm: float) -> np.ndarray:
    """The sponge's force law as it was before the model family (commit bd1debd)."""
    y, z = float(pos[1]), float(pos[2])
    if not p.z_bottom_mm <= z <= p.z_top_mm:
        return np.zeros(3)
    travelled = p.z_top_mm - z
    wave = p.waviness_mm * math.sin(2 * math.pi * travelled / p.waviness_wavelength_mm)
    sunk = p.set_mm * (1 - math.exp(-passes / p.set_passes))
    depth = max(0.0, p.surface_y_mm + p.surface_slope * travelled + wave - sunk - y)
    if depth <= 0.0:
        return np.zeros(3)
    wavelength = p.stiffness_wavelength_mm
    variation = p.stiffness_variation * math.cos(2 * math.pi * travelled / wavelength)
    softened = 1 - p.softening * (1 - math.exp(-passes / p.softening_passes))
    k = p.stiffness_n_per_mm * (1 + variation) * softened
    normal_n = k * max(0.0, min(depth, p.thickness_mm) + p.relaxation_ratio * relaxing_mm)
    normal_n += p.backing_n_per_mm * max(0.0, depth - p.thickness_mm)
    wk = 2 * math.pi / p.waviness_wavelength_mm
    dy_dz = -p.surface_slope - p.waviness_mm * wk * math.cos(wk * travelled)
    direction = np.array([0.0, 1.0, -dy_dz])
    return normal_n * direction / np.linalg.norm(direction)


def test_defaults_give_the_linear_law_bit_for_bit() -> None:
    """At the defaults every force equals the old formula exactly, over depth, height, wear."""
    p = SpongeParams()
    rng = np.random.default_rng(7)
    for _ in range(2000):
        pos = _at(rng.uniform(-50, 6), rng.uniform(-125, 25))
        passes, relaxing = int(rng.integers(0, 400)), float(rng.uniform(-3, 3))
        assert np.array_equal(contact_force_n(p, passes, pos, relaxing),
                              _linear_law(p, passes, pos, relaxing))


def test_defaults_keep_the_sponge_object_linear_along_a_path() -> None:
    """Pressing, sliding and easing off leave no hysteresis or friction at the defaults."""
    sponge = Sponge()
    for y, z in [(-2.0, 0.0), (-6.0, -5.0), (-8.0, -10.0), (-4.0, -15.0), (-7.0, -20.0)]:
        sponge.observe_pose(_at(y, z))
        sponge.evolve(_at(y, z), 0.05)
        force = sponge.contact_force_world_n(_at(y, z))
        assert np.array_equal(force, _linear_law(sponge.params, 0, _at(y, z), sponge.relaxing_mm))


def _normal_n(p: SpongeParams, depth_mm: float) -> float:
    surface = surface_y_mm(p, 0, Z)
    return float(np.linalg.norm(contact_force_n(p, 0, _at(surface - depth_mm))))


def test_power_law_stiffens_and_meets_the_linear_law_at_the_reference_depth() -> None:
    """Power n > 1: secant stiffness grows; force = k * d at d_ref; IFD ratio = 2.6 ** n."""
    p = SpongeParams(stiffening_exponent=1.4, stiffening_reference_mm=10.0)
    k = stiffness_n_per_mm(p, 0, Z)
    assert _normal_n(p, 10.0) == pytest.approx(k * 10.0, rel=1e-12)
    secants = [_normal_n(p, d) / d for d in (2.0, 5.0, 10.0, 20.0, 30.0)]
    assert all(b > a for a, b in itertools.pairwise(secants))
    assert _normal_n(p, 26.0) / _normal_n(p, 10.0) == pytest.approx(2.6**1.4, rel=1e-9)
    assert _normal_n(p, 5.0) < k * 5.0 and _normal_n(p, 20.0) > k * 20.0


def _press_path(sponge: Sponge, depths: list[float]) -> list[float]:
    """Move the tool through foam depths at fixed Z; the normal force (N) at each."""
    surface = surface_y_mm(sponge.params, 0, Z)
    forces = []
    for depth in depths:
        sponge.observe_pose(_at(surface - depth))
        forces.append(float(np.linalg.norm(sponge.contact_force_world_n(_at(surface - depth)))))
    return forces


def test_hysteresis_loading_force_exceeds_unloading_at_the_same_depth() -> None:
    """Pressing in meets (1 + h) times the elastic force, easing off (1 - h) times it."""
    h = 0.2
    p = SpongeParams(hysteresis_loss=h, hysteresis_depth_mm=0.5, relaxation_ratio=0.0)
    sponge = Sponge(p)
    down = list(np.arange(0.1, 14.0, 0.1))
    up = list(np.arange(14.0, 2.0, -0.1))
    loading = dict(zip((round(d, 1) for d in down), _press_path(sponge, down), strict=True))
    unloading = dict(zip((round(d, 1) for d in up), _press_path(sponge, up), strict=True))
    elastic = _normal_n(SpongeParams(relaxation_ratio=0.0), 8.0)
    assert loading[8.0] > unloading[8.0]
    assert loading[8.0] == pytest.approx((1 + h) * elastic, rel=1e-4)
    assert unloading[8.0] == pytest.approx((1 - h) * elastic, rel=1e-4)


def test_hysteresis_is_continuous_at_a_reversal_and_rate_independent() -> None:
    """A tiny reversal changes the force a little (no jump); step size does not matter."""
    p = SpongeParams(hysteresis_loss=0.25, relaxation_ratio=0.0)
    fine, coarse = Sponge(p), Sponge(p)
    before = _press_path(fine, list(np.linspace(0.05, 10.0, 400)))[-1]
    after = _press_path(fine, [9.99])[-1]
    assert before - after < 0.02 * before
    assert _press_path(coarse, [10.0])[-1] == pytest.approx(before, rel=1e-9)


def test_travel_onto_fresh_foam_drives_the_hysteresis_towards_loading() -> None:
    """Rolling along Z presses fresh foam: after easing off, travel brings s back towards +1."""
    p = SpongeParams(hysteresis_loss=0.2, relaxation_ratio=0.0, surface_slope=0.0,
                     waviness_mm=0.0, hysteresis_travel_mm=10.0)
    still, rolling = Sponge(p), Sponge(p)
    for sponge in (still, rolling):
        _press_path(sponge, [*np.arange(0.1, 10.0, 0.1), 9.0])  # press, then ease 1 mm
    assert still.hysteresis_state < -0.6
    y = surface_y_mm(p, 0, Z) - 9.0
    rolling.observe_pose(_at(y, Z - 10.0))  # roll one travel length at the same depth
    expected = 1.0 + (still.hysteresis_state - 1.0) * math.exp(-1.0)
    assert rolling.hysteresis_state == pytest.approx(expected, rel=1e-12)
    rolling.observe_pose(_at(y, Z - 60.0))
    assert rolling.hysteresis_state > 0.99


def test_friction_opposes_the_slide_and_scales_with_the_normal_force() -> None:
    """Sliding down Z the tool feels mu * N upward along the surface; sliding up, downward."""
    mu = 0.3
    p = SpongeParams(friction_coefficient=mu)
    for depth in (4.0, 9.0):
        sponge = Sponge(p)
        surface = surface_y_mm(p, 0, Z)
        sponge.observe_pose(_at(surface - depth, Z + 1.0))
        sponge.observe_pose(_at(surface - depth, Z))
        force = sponge.contact_force_world_n(_at(surface - depth, Z))
        normal = surface_normal(p, Z)
        normal_part = float(force @ normal)
        tangential = force - normal_part * normal
        assert normal_part == pytest.approx(_normal_n(SpongeParams(), depth), rel=1e-12)
        assert np.linalg.norm(tangential) == pytest.approx(mu * normal_part, rel=1e-12)
        assert tangential[2] > 0  # the tool moved -Z: friction pushes it +Z
        sponge.observe_pose(_at(surface - depth, Z + 0.5))  # slide back up
        back = sponge.contact_force_world_n(_at(surface - depth, Z + 0.5))
        assert back[2] < 0


def test_friction_stays_at_rest_ignores_normal_moves_and_ends_off_the_foam() -> None:
    """The last slide holds while the tool rests or presses along Y; leaving the foam clears it."""
    p = SpongeParams(friction_coefficient=0.4)
    sponge = Sponge(p)
    surface = surface_y_mm(p, 0, Z)
    sponge.observe_pose(_at(surface - 5.0, Z + 1.0))
    assert sponge.slide_direction == (0.0, 0.0, 0.0)  # no slide yet: no friction
    sponge.observe_pose(_at(surface - 5.0, Z))
    slid = sponge.slide_direction
    normal = surface_normal(p, Z)
    sponge.observe_pose(_at(surface - 5.0, Z) - 2.0 * normal)  # straight along the normal
    assert sponge.slide_direction == slid
    sponge.observe_pose(_at(surface + 5.0, Z))
    assert sponge.slide_direction == (0.0, 0.0, 0.0)


def test_friction_shows_in_the_sensor_wrench_and_is_absent_at_mu_zero() -> None:
    """Through the cell: a slide down Z gives the sensor a +Fz that mu = 0 does not."""
    readings = {}
    for mu in (0.0, 0.3):
        physics = CellPhysics(Sponge(SpongeParams(friction_coefficient=mu)))
        surface = surface_y_mm(SpongeParams(), 0, Z)
        physics.set_pose(Pose(900.0, surface - 6.0, Z + 2.0))
        physics.set_pose(Pose(900.0, surface - 6.0, Z))
        readings[mu] = physics.true_wrench()
    gained = readings[0.3][:3] - readings[0.0][:3]
    assert gained[2] == pytest.approx(0.3 * np.linalg.norm(readings[0.0][:3]), rel=0.01)


def test_state_round_trip_carries_hysteresis_and_friction() -> None:
    """A sponge restored (through JSON) mid-path gives the same forces on the same moves."""
    p = SpongeParams(stiffening_exponent=1.3, hysteresis_loss=0.2, friction_coefficient=0.25)
    sponge = Sponge(p, passes=12)
    surface = surface_y_mm(p, 12, Z)
    for y, z in [(surface - 3, Z + 5), (surface - 8, Z), (surface - 6, Z - 2)]:
        sponge.observe_pose(_at(y, z))
        sponge.evolve(_at(y, z), 0.04)
    other = Sponge(p)
    other.load_state_dict(json.loads(json.dumps(sponge.state_dict())))
    for y, z in [(surface - 5, Z - 2), (surface - 5, Z - 4), (surface - 9, Z - 4)]:
        for s in (sponge, other):
            s.observe_pose(_at(y, z))
            s.evolve(_at(y, z), 0.04)
        assert np.array_equal(other.contact_force_world_n(_at(y, z)),
                              sponge.contact_force_world_n(_at(y, z)))
    assert other.state_dict() == sponge.state_dict()


@pytest.mark.parametrize(
    ("field", "value"),
    [("stiffening_exponent", 0.2), ("stiffening_exponent", 4.0), ("stiffening_reference_mm", 0.0),
     ("hysteresis_loss", -0.1), ("hysteresis_loss", 1.0), ("hysteresis_depth_mm", 0.0),
     ("hysteresis_travel_mm", -1.0),
     ("friction_coefficient", -0.2), ("friction_coefficient", math.inf)],
)
def test_new_params_refuse_values_out_of_range(field: str, value: float) -> None:
    """Each new key is checked and the message names it."""
    with pytest.raises(ValueError, match=field):
        SpongeParams(**{field: value})
