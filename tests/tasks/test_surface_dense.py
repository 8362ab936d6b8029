"""Stiff parts: the probe measures every step's Z where its surface is not resolved."""

from __future__ import annotations

import math

import numpy as np
import pytest

from forcelearn.errors import ConfigError
from forcelearn.tasks.surface import SurfaceTaskSpec
from forcelearn.tasks.surface_fit import ContactFit, ProbeResult, ProbeSpec
from forcelearn.tasks.surface_map import DENSE_ABOVE, dense_points

PROBED_Z_MM = (0.0, -12.5, -25.0, -37.5, -50.0, -62.5, -75.0, -87.5, -100.0)


def _probe(stiffness: float, wave_mm: float) -> ProbeResult:
    """Fits along the path of a surface with waves of 80 mm and ``wave_mm`` amplitude."""
    fits = [ContactFit(z, stiffness, 0.01, wave_mm * math.sin(2 * math.pi * -z / 80.0), 0.01,
                       0.05, 6) for z in PROBED_Z_MM]
    return ProbeResult(fits=fits, baselines_n=[0.0] * len(fits))


def test_a_stiff_wavy_part_at_a_small_force_gets_every_steps_z() -> None:
    """6 N/mm, 3 mm waves, 0.75 kgf: the band is 0.06 mm; the steps between points are probed."""
    task = SurfaceTaskSpec(desired_force_n=7.36)
    added = dense_points(_probe(6.0, 3.0), task)
    probed = {round(-z / task.path_mm, 6) for z in PROBED_Z_MM}
    assert added and not probed & set(added)
    assert all(0 < f <= 1 and round(f * task.steps_per_trial) == f * task.steps_per_trial
               for f in added)


def test_the_default_sponge_is_resolved_by_its_probe_points() -> None:
    """2 N/mm, 1 mm waves, 2 kgf: no point added."""
    assert dense_points(_probe(2.0, 1.0), SurfaceTaskSpec()) == ()


def test_the_new_keys_are_checked_at_load() -> None:
    """task.approach and probe.ease_off_mm refuse what they cannot use, naming the key."""
    with pytest.raises(ConfigError, match=r"task\.approach"):
        SurfaceTaskSpec(approach="sideways")
    with pytest.raises(ConfigError, match=r"probe\.ease_off_mm"):
        ProbeSpec(ease_off_mm=(0.5, -1.0))
    assert SurfaceTaskSpec(approach="direction").grid().ndim == 2


def test_a_long_probe_brings_its_fits_to_the_foam_its_last_point_found() -> None:
    """The first point re-probed last: its drift spreads over the fits in probing order."""
    fits = [ContactFit(-10.0 * i, 4.0, 0.01, 1.0, 0.01, 0.05, 6) for i in range(4)]
    fits.append(ContactFit(0.0, 3.6, 0.01, 0.6, 0.01, 0.05, 6))  # the first Z, sunk and softer
    probe = ProbeResult(fits=fits, baselines_n=[0.0] * 5)
    shift, ratio = probe.correct_drift()
    assert shift == pytest.approx(-0.4) and ratio == pytest.approx(0.9)
    assert [f.contact_y_mm for f in probe.fits] == pytest.approx([0.6, 0.7, 0.8, 0.9, 0.6])
    assert probe.fits[0].stiffness_n_per_mm == pytest.approx(3.6)
    assert probe.fits[2].stiffness_n_per_mm == pytest.approx(4.0 * 0.9**0.5)


def test_every_step_the_probed_grid_misses_by_two_bands_is_probed() -> None:
    """The emulated sponge's waves at 8 N/mm, 5 N, probed at the 7 points of a refined probe.

    The curvature check of the point at -12.5 mm (neighbours 0 and -37.5 mm) underestimates
    the wave's crest at the path's start: steps whose interpolated target misses the foam's by
    more than ``DENSE_ABOVE`` bands must be probed all the same.
    """
    stiffness, force = 8.0, 5.0
    task = SurfaceTaskSpec(desired_force_n=force)
    probed_z = (0.0, -12.5, -37.5, -50.0, -62.5, -87.5, -100.0)

    def surface(z: float) -> float:
        return 0.03 * (20.0 - z) + math.sin(2 * math.pi * (20.0 - z) / 80.0)

    fits = [ContactFit(z, stiffness, 0.01, surface(z), 0.01, 0.05, 6) for z in probed_z]
    added = set(dense_points(ProbeResult(fits=fits, baselines_n=[0.0] * len(fits)), task))
    grid = sorted(probed_z)
    band = 0.05 * force
    for step in range(1, task.steps_per_trial + 1):
        z = task.start_mm[2] + task.z_step_mm * step
        miss = stiffness * abs(surface(z) - float(np.interp(z, grid, [surface(v) for v in grid])))
        if miss > DENSE_ABOVE * band:
            assert step / task.steps_per_trial in added, f"step {step}: {miss:.2f} N missed"


def test_a_re_probe_midway_follows_a_set_that_slows_with_the_passes() -> None:
    """The first Z probed first, midway and last: every fit ends on the foam as it is now.

    The foam sinks 0.3 mm over the first three passes and 0.1 mm over the last three
    (linearly within each): with the midway reading, each fit moves by the set still to come.
    """
    def sunk(i: int) -> float:
        return -0.1 * i if i <= 3 else -0.3 - 0.1 * (i - 3) / 3

    surface = {0.0: 1.0, -10.0: 0.8, -20.0: 0.6, -30.0: 0.4, -40.0: 0.2}
    order = (0.0, -10.0, -20.0, 0.0, -30.0, -40.0, 0.0)
    fits = [ContactFit(z, 4.0, 0.01, surface[z] + sunk(i), 0.01, 0.05, 6)
            for i, z in enumerate(order)]
    probe = ProbeResult(fits=fits, baselines_n=[0.0] * len(fits))
    shift, _ = probe.correct_drift()
    assert shift == pytest.approx(-0.4)
    assert [f.contact_y_mm for f in probe.fits] == pytest.approx(
        [surface[z] - 0.4 for z in order])
