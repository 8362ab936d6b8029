"""The twin's forward model and the emulated sponge are one law.

The forward model reads :func:`~forcelearn.emulators.physics.sponge_law.contact_force_n`
over arrays; the emulated :class:`Sponge` evaluates it one pose at a time with its state.
On every member of the foam family they agree to rounding at thousands of points.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import Sponge, SpongeParams
from forcelearn.emulators.physics.sponge_law import (
    depth_for_force_mm,
    hysteresis_step,
    normal_force_n,
    stiffness_n_per_mm,
)
from forcelearn.tools.twin import forward
from forcelearn.tools.twin.simulate import DOWN

READING = forward.Reading.of(DOWN, 1, -1.0)
TILTED = forward.Reading(along_y=-0.8, along_z=0.6)
POINTS = 2000
BASE = SpongeParams()
MEMBERS = {
    "linear-elastic": {"relaxation_ratio": 0.0, "softening": 0.0, "set_mm": 0.0},
    "linear": {},
    "wear": {"softening": 0.6, "softening_passes": 20.0, "set_mm": 4.0, "set_passes": 15.0},
    "relaxation": {"relaxation_ratio": 2.0, "relaxation_time_s": 0.1},
    "nonlinear": {"stiffening_exponent": 1.4, "stiffening_reference_mm": 7.0},
    "softening-law": {"stiffening_exponent": 0.7},
    "hysteretic": {"stiffening_exponent": 1.2, "hysteresis_loss": 0.3,
                   "hysteresis_depth_mm": 0.8},
    "friction": {"friction_coefficient": 0.4, "surface_slope": 0.12},
    "hysteretic+friction": {"hysteresis_loss": 0.2, "friction_coefficient": 0.3,
                            "waviness_mm": 2.5, "stiffness_variation": 0.4},
    "backing": {"thickness_mm": 6.0, "backing_n_per_mm": 150.0},
}


def _points(p: SpongeParams, seed: int) -> dict[str, np.ndarray]:
    """Tool points over the strip and past its ends, each with a sponge state."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(p.z_bottom_mm - 10.0, p.z_top_mm + 10.0, POINTS)
    angle = rng.uniform(0.0, 2 * np.pi, POINTS)
    slid = rng.random(POINTS) < 0.8
    return {
        "passes": rng.integers(0, 400, POINTS).astype(float),
        "y": rng.uniform(-p.thickness_mm - 8.0, 6.0, POINTS),
        "z": z,
        "q": rng.uniform(-1.0, 3.0, POINTS),
        "s": rng.uniform(-1.0, 1.0, POINTS),
        "slide_y": np.where(slid, np.cos(angle), 0.0),
        "slide_z": np.where(slid, np.sin(angle), 0.0),
    }


def _emulated(p: SpongeParams, at: dict[str, np.ndarray], reading: forward.Reading
              ) -> np.ndarray:
    """The emulated sponge's reading at each point, one pose at a time, with its state."""
    sponge = Sponge(p)
    readings = []
    for i in range(POINTS):
        sponge.passes = int(at["passes"][i])
        sponge.relaxing_mm = float(at["q"][i])
        sponge.hysteresis_state = float(at["s"][i])
        sponge.slide_direction = (0.0, float(at["slide_y"][i]), float(at["slide_z"][i]))
        force = sponge.contact_force_world_n(np.array([900.0, at["y"][i], at["z"][i]]))
        readings.append(force[1] * reading.along_y + force[2] * reading.along_z)
    return np.array(readings)


@pytest.mark.parametrize("member", MEMBERS)
@pytest.mark.parametrize("reading", [READING, TILTED], ids=["normal", "tilted"])
def test_forward_model_is_the_emulated_sponge(member: str, reading: forward.Reading) -> None:
    """Every foam member: the forward model's readings equal the emulator's to 1e-12."""
    p = dataclasses.replace(BASE, **MEMBERS[member])
    at = _points(p, seed=len(member))
    contact = forward.ContactState(at["s"], at["slide_y"], at["slide_z"])
    ours = forward.recorded_force_n(p, at["passes"], at["y"], at["z"], at["q"], reading,
                                    contact)
    theirs = _emulated(p, at, reading)
    assert np.count_nonzero(theirs) > POINTS // 2  # most points press the foam
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12)


def test_the_law_takes_floats_and_arrays_alike() -> None:
    """Scalar and array calls of the law's functions give the same numbers."""
    p = dataclasses.replace(BASE, **MEMBERS["hysteretic"])
    at = _points(p, seed=7)
    depth = np.abs(at["y"]) / 2
    array = normal_force_n(p, at["passes"], depth, at["z"], at["q"], at["s"])
    scalar = [normal_force_n(p, float(n), float(d), float(z), float(q), float(s))
              for n, d, z, q, s in zip(at["passes"], depth, at["z"], at["q"], at["s"],
                                       strict=True)]
    np.testing.assert_allclose(array, scalar, rtol=1e-12, atol=1e-12)
    change, travel = at["q"], np.abs(at["y"]) / 4
    array = hysteresis_step(p, at["s"], change, travel)
    scalar = [hysteresis_step(p, float(s), float(c), float(t))
              for s, c, t in zip(at["s"], change, travel, strict=True)]
    np.testing.assert_allclose(array, scalar, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("exponent", [0.7, 1.0, 1.5])
def test_depth_for_force_is_the_laws_inverse(exponent: float) -> None:
    """The inverse beside the law: the depth it gives pushes the force asked for."""
    p = dataclasses.replace(BASE, stiffening_exponent=exponent, relaxation_ratio=0.0)
    z = np.linspace(p.z_bottom_mm, p.z_top_mm, 50)
    force = np.linspace(0.5, 40.0, 50)
    depth = depth_for_force_mm(p, force, stiffness_n_per_mm(p, 0.0 * z, z))
    assert np.all(depth < p.thickness_mm)
    np.testing.assert_allclose(normal_force_n(p, 0.0 * z, depth, z), force, rtol=1e-12)
