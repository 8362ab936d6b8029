"""The sponge's force with its depth remembered and its surface terms kept per height, to the bit.

``Sponge.contact_force_world_n`` takes the point's depth from the sponge's memo and the
surface direction and length from a per-height cache (``direction_terms``); it must give
``contact_force_n`` of the point exactly, whatever the material, state and point.
"""

from __future__ import annotations

import random

import numpy as np

from forcelearn.emulators.physics.sponge import Sponge, SpongeParams, contact_force_n, surface_y_mm


def test_the_kept_terms_give_contact_force_n_to_the_bit() -> None:
    """Random materials, states, points on and off the strip (heights repeated), tuples, arrays."""
    rng = random.Random(5)
    materials = [SpongeParams(), SpongeParams(hysteresis_loss=0.3, stiffening_exponent=1.3,
                                              friction_coefficient=0.4),
                 SpongeParams(relaxation_ratio=0.0, waviness_mm=2.0)]
    pressed = 0
    for params in materials:
        sponge = Sponge(params)
        heights = [rng.uniform(params.z_bottom_mm - 5.0, params.z_top_mm + 5.0) for _ in range(6)]
        for _ in range(400):
            sponge.passes = rng.randint(0, 5)
            sponge.relaxing_mm = rng.uniform(-1.0, 2.0)
            sponge.hysteresis_state = rng.uniform(-1.0, 1.0)
            sponge.slide_direction = rng.choice([(0.0, 0.0, 0.0), (0.0, 0.6, 0.8)])
            z = rng.choice(heights)
            y = surface_y_mm(params, sponge.passes, z) - rng.uniform(-3.0, 12.0)
            point = (rng.uniform(-5.0, 5.0), y, z)
            given = point if rng.random() < 0.5 else np.array(point)
            got = sponge.contact_force_world_n(given)
            expected = contact_force_n(params, sponge.passes, np.array(point), sponge.relaxing_mm,
                                       sponge.hysteresis_state, sponge.slide_direction)
            assert got.tobytes() == expected.tobytes()
            pressed += bool(got.any())
    assert pressed > 300
