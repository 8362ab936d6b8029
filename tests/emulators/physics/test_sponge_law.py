"""The sponge law's one-point hot path against the law it writes out."""

from __future__ import annotations

import math

import numpy as np

from forcelearn.emulators.physics.sponge_law import (
    SpongeParams,
    _surface_y_mm,
    point_penetration_mm,
)


def test_a_points_penetration_is_the_surface_law_to_the_bit() -> None:
    """The written-out surface of ``point_penetration_mm`` is ``_surface_y_mm``'s, to the bit.

    With ``math.sin``, on and off the strip, for sunk and waved surfaces.
    """
    rng = np.random.default_rng(11)
    for params in (SpongeParams(), SpongeParams(waviness_mm=2.5, surface_slope=-0.07)):
        for _ in range(2000):
            set_mm = float(rng.uniform(0.0, 3.0))
            y_mm = float(rng.uniform(-10.0, 10.0))
            z_mm = float(rng.uniform(params.z_bottom_mm - 10.0, params.z_top_mm + 10.0))
            inside = params.z_bottom_mm <= z_mm <= params.z_top_mm
            surface = _surface_y_mm(params, set_mm, z_mm, math.sin)
            law = max(0.0, surface - y_mm) if inside else 0.0
            assert point_penetration_mm(params, set_mm, y_mm, z_mm) == law
