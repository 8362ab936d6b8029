"""`forcelearn calibrate` over an emulated EGM robot and Net F/T box."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from forcelearn.calibration import load_calibration
from forcelearn.site.config import load_cell_config
from forcelearn.site.netft_kind import box_model
from forcelearn.tools.commands.calibrate import calibrate
from forcelearn.tools.experiments.calibration_plan import CalibrationPlan

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "egm-netft-cell.toml"
FAST = CalibrationPlan(record_s=0.5, samples_per_pose=800, settle_s=0.2, settle_timeout_s=5.0)


def test_calibrate_over_egm_and_netft_records_the_box_and_its_noise(tmp_path: Path) -> None:
    """The file names the Net F/T and EGM, its ranges, and the emulated box's noise (±20 %)."""
    config = load_cell_config(EXAMPLE)
    out = tmp_path / "cal.toml"
    cal = calibrate(config, FAST, out_path=out, seed=1, progress=False, stream=io.StringIO())
    assert load_calibration(out) == cal
    assert cal.sensor.model == "ATI Net F/T (forcelearn emulator)"
    assert cal.sensor.robot == "ABB EGM rw6"
    assert cal.sensor.full_scales == box_model(config).ranges
    truth = np.array(box_model(config).noise_std)
    assert np.all(np.abs(np.asarray(cal.noise.std) / truth - 1.0) < 0.2)
