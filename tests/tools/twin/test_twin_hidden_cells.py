"""The hidden-cell generator: stated ranges, runnable configs, truth beside them."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import (
    SpongeParams,
    contact_force_n,
    depth_for_force_mm,
    stiffness_n_per_mm,
    surface_y_mm,
)
from forcelearn.site.config import load_cell_config
from forcelearn.site.jr3_kind import sensor_model
from forcelearn.tasks.surface import KGF_N
from forcelearn.tools.twin.hidden_cells import (
    HiddenCellRanges,
    draw_hidden_cell,
    main,
    write_hidden_cells,
)

RANGES = HiddenCellRanges()
DRAWS = [draw_hidden_cell(seed, i) for seed in (0, 1, 2, 3) for i in range(1, 51)]


def _inside(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] <= value <= bounds[1]


def test_every_drawn_parameter_lies_in_its_stated_range() -> None:
    """Stiffness, force, wear, relaxation, lag, noise and the model terms stay in range."""
    base = SpongeParams()
    for cell in DRAWS:
        s = cell.sponge
        assert _inside(s.stiffness_n_per_mm, RANGES.stiffness_n_per_mm)
        assert _inside(cell.desired_force_n / KGF_N, RANGES.desired_force_kgf)
        assert _inside(cell.wear_rate, RANGES.wear_rate)
        assert s.softening_passes == pytest.approx(base.softening_passes / cell.wear_rate, 1e-5)
        assert s.set_mm == pytest.approx(base.set_mm * cell.wear_amplitude, 1e-5)
        assert _inside(s.relaxation_ratio, RANGES.relaxation_ratio)
        assert _inside(cell.lag_s, RANGES.lag_s) and _inside(cell.noise_n, RANGES.noise_n)
        assert _inside(cell.accel_mm_s2, RANGES.accel_mm_s2)
        assert s.stiffening_exponent == 1.0 or _inside(s.stiffening_exponent,
                                                       RANGES.stiffening_exponent)
        assert s.hysteresis_loss == 0.0 or _inside(s.hysteresis_loss, RANGES.hysteresis_loss)
        assert s.friction_coefficient == 0.0 or _inside(s.friction_coefficient,
                                                        RANGES.friction_coefficient)


def test_draws_span_the_ranges_and_every_model_member() -> None:
    """Soft and stiff foams, small and large forces, and every model term on and off."""
    k = [c.sponge.stiffness_n_per_mm for c in DRAWS]
    force = [c.desired_force_n / KGF_N for c in DRAWS]
    assert min(k) < 0.8 and max(k) > 6.0
    assert min(force) < 0.8 and max(force) > 2.7
    assert min(c.wear_rate for c in DRAWS) < 0.5 and max(c.wear_rate for c in DRAWS) > 3.5
    accel = [c.accel_mm_s2 for c in DRAWS]  # an acceleration left at the default checks nothing
    assert min(accel) < 500 and max(accel) > 2000
    for share, flags in [
        (RANGES.nonlinear_share, [c.sponge.stiffening_exponent != 1.0 for c in DRAWS]),
        (RANGES.hysteresis_share, [c.sponge.hysteresis_loss != 0.0 for c in DRAWS]),
        (RANGES.friction_share, [c.sponge.friction_coefficient != 0.0 for c in DRAWS]),
    ]:
        assert abs(np.mean(flags) - share) < 0.15


def test_derived_settings_leave_room_for_the_task() -> None:
    """Force limit above the task, foam deep enough for it when worn, start press near half."""
    for cell in DRAWS:
        s, d = cell.sponge, cell.derived
        assert d["max_force_n"] == pytest.approx(3 * cell.desired_force_n, rel=1e-5)
        worn = (s.stiffness_n_per_mm * (1 - s.stiffness_variation) * (1 - s.softening)
                * (1 - s.hysteresis_loss))
        needed = depth_for_force_mm(s, cell.desired_force_n, worn) + s.set_mm
        assert 1.1 * needed < d["probe_max_depth_mm"] < s.thickness_mm
        start = np.array([d["start_x_mm"], d["start_y_mm"], d["start_z_mm"]])
        start_n = float(np.linalg.norm(contact_force_n(s, 0, start)))
        slope = stiffness_n_per_mm(s, 0, start[2]) * 0.05 * s.stiffening_exponent * 3
        assert start_n == pytest.approx(0.5 * cell.desired_force_n, abs=slope + 0.02)
        assert d["retract_y_mm"] >= surface_y_mm(s, 0, d["start_z_mm"]) + 10
        assert d["workspace_min_y_mm"] < surface_y_mm(s, 0, -100.0) - s.thickness_mm
        assert d["probe_dwell_s"] >= 4 * s.relaxation_time_s * (1 - 1e-5)
        assert d["probe_contact_force_n"] >= max(1.0, 3 * cell.noise_n) * (1 - 1e-5)
        assert 16 <= d["probe_samples"] <= 400
        if cell.noise_n > 0.5:  # averages as long as today's 0.2 N sensor, up to 400 samples
            assert d["probe_samples"] >= min(400, 16 * (0.5 / 0.2) ** 2)


def test_written_cells_load_as_run_configs_and_match_their_truth(tmp_path: Path) -> None:
    """Each TOML runs through the run's loader; its physics equals the truth JSON beside it."""
    paths = write_hidden_cells(4, 5, tmp_path)
    manifest = json.loads((tmp_path / "hidden-cells.json").read_text())
    assert [c["config"] for c in manifest["cells"]] == [p.name for p in paths]
    for path in paths:
        config = load_cell_config(path)
        truth = json.loads(path.with_suffix(".truth.json").read_text())
        assert asdict(config.emulator.sponge) == truth["sponge"]
        assert config.emulator.arm.lag_s == truth["arm"]["lag_s"]
        assert config.emulator.arm.accel_mm_s2 == truth["arm"]["accel_mm_s2"]
        assert sensor_model(config).noise_std[:3] == (truth["sensor"]["noise_n"],) * 3
        assert config.task.desired_force_n == truth["task"]["desired_force_n"]
        assert config.safety.max_force_n > config.task.desired_force_n
        assert math.isclose(config.filter.measurement_variance_n2,
                            truth["sensor"]["noise_n"] ** 2, rel_tol=1e-5)


def test_same_seed_same_cells_whatever_the_count(tmp_path: Path) -> None:
    """Cell i of a seed is the same file with 2 or 3 cells drawn; another seed differs."""
    write_hidden_cells(2, 9, tmp_path / "a")
    main(["--count", "3", "--seed", "9", "--out", str(tmp_path / "b")])
    write_hidden_cells(2, 10, tmp_path / "c")
    for name in ("cell-01.toml", "cell-02.truth.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert (tmp_path / "a/cell-01.toml").read_bytes() != (tmp_path / "c/cell-01.toml").read_bytes()
    assert (tmp_path / "b/cell-03.toml").exists()


def test_bad_count_and_ranges_are_refused(tmp_path: Path) -> None:
    """A count below 1, or a range upside down, is a ValueError that names it."""
    with pytest.raises(ValueError, match="count"):
        write_hidden_cells(0, 1, tmp_path)
    with pytest.raises(ValueError, match="lag_s"):
        HiddenCellRanges(lag_s=(0.2, 0.01))
    with pytest.raises(SystemExit):
        main(["--count", "0", "--out", str(tmp_path)])


def test_shaped_cells_draw_their_own_periodic_shapes_and_leave_every_other_draw() -> None:
    """``shaped_share`` gives a strip its own waviness and stiffness variation, in range.

    The other draws of the seed stay those of an unshaped study (its cells run as before).
    """
    shaped = HiddenCellRanges(shaped_share=1.0)
    base = SpongeParams()
    shapes = ("waviness_mm", "waviness_wavelength_mm", "stiffness_variation",
              "stiffness_wavelength_mm")
    for seed, i in [(0, 1), (1, 7), (2, 30), (3, 12)]:
        plain, own = draw_hidden_cell(seed, i), draw_hidden_cell(seed, i, shaped)
        assert all(getattr(plain.sponge, n) == getattr(base, n) for n in shapes)
        for n in shapes:
            assert _inside(getattr(own.sponge, n), getattr(shaped, n))
        assert own.sponge.waviness_wavelength_mm != base.waviness_wavelength_mm
        for n in ("stiffness_n_per_mm", "surface_y_mm", "relaxation_ratio", "softening",
                  "stiffening_exponent", "hysteresis_loss", "friction_coefficient"):
            assert getattr(own.sponge, n) == getattr(plain.sponge, n)
        assert (own.lag_s, own.noise_n, own.accel_mm_s2, own.desired_force_n) == (
            plain.lag_s, plain.noise_n, plain.accel_mm_s2, plain.desired_force_n)
