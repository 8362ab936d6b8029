"""The forward model replays an identification's steps as the emulated cell made them.

A step of the step-and-hold takes 0.2-0.6 s from the command to in position (the servo
lag), and the lagging tool enters the in-position band short of the target: on a fast
foam most of the relaxation happens during the move, so the holds' bursts see the tail
of it, and what the model makes of the move's end decides the relaxation it fits.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge_law import SpongeParams
from forcelearn.site.config import load_cell_config
from forcelearn.tools.twin.arm import ArmFit, polling_of, with_true_in_position
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import predict_means, within_burst_variance
from forcelearn.tools.twin.hidden_cells import HiddenCellRanges, cell_config, draw_hidden_cell
from forcelearn.tools.twin.identify import IdentifyPlan, run_identification
from forcelearn.tools.twin.identify_fit import fit_timing
from forcelearn.tools.twin.problem import Problem
from forcelearn.tools.twin.setup import base_sponge, reading_of

FAST_FOAM = 10
"""Hidden cell 10 of seed 1: a stiffening foam relaxing by 0.32 in 0.25 s, arm lag 0.093 s."""


@pytest.fixture(scope="module")
def quiet_step_and_hold(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, ...]:
    """The cell without sensor noise or drift, an identification's holds and the arm it fits."""
    import tomli_w

    cell = cell_config(draw_hidden_cell(1, FAST_FOAM, HiddenCellRanges()))
    cell["emulator"]["sensor"] = {"noise_std": [1e-4] * 3 + [1e-5] * 3,
                                  "bias_drift_per_sqrt_s": [0.0] * 6}
    path = tmp_path_factory.mktemp("cell") / "cell.toml"
    path.write_text(tomli_w.dumps(cell), encoding="utf-8")
    config = load_cell_config(path)
    plan = IdentifyPlan(lengths_mm=(1.0, 2.0, 3.5, 5.0, 7.0, 9.5), free_reads=1,
                        free_hold_s=0.5, hold_steps=3,
                        hold_s=(0.04, 0.08, 0.12, 0.16, 0.2, 0.3, 0.4, 0.6, 1.0, 1.5), cycles=0)
    result = run_identification(config, plan, seed=0)
    timing = fit_timing(result.moves)
    assert timing is not None
    arm = {k: v for k, v in timing.values.items() if k != "speed_scale"}
    arm["default_speed_mm_s"] = 100.0  # never reached by these steps (accel-limited)
    polling = polling_of(config.robot, ArmConfig())
    fitted = ArmFit(arm, dict.fromkeys(arm, 0.0), timing.rms_s, timing.moves, "",
                    polling.period_s, arm, {}, polling.answer_s(polling.period_s))
    data = with_true_in_position(to_arrays(result.records), fitted, ArmConfig().in_position_mm)
    truth = {**base_sponge(config), **{k: float(v) for k, v in cell["emulator"]["sponge"].items()}}
    stages = np.array([s.stage for t in result.records for s in t.steps])
    holds = np.zeros(data.has_burst.shape, bool)
    holds[0, :stages.size] = np.isin(stages, ["identify-step", "identify-hold"])
    return config, data, arm, truth, holds


def test_the_holds_are_predicted_at_the_truth(quiet_step_and_hold: tuple[Any, ...]) -> None:
    """Every burst of the step-and-hold within 0.02 N of the model at the cell's own values.

    With the move taken to end at its target (and a hold's still step to start after the
    start delay, as if commanded) they were up to 0.048 N off.
    """
    config, data, arm, truth, holds = quiet_step_and_hold
    predicted = predict_means(data, SpongeParams.unchecked(truth), arm, reading_of(config))
    held = holds & data.has_burst
    assert held.sum() >= 20
    assert np.max(np.abs(predicted - data.mean_n)[held]) < 0.02


def test_the_relaxation_fitted_to_the_holds_is_the_cells(
        quiet_step_and_hold: tuple[Any, ...]) -> None:
    """Ratio and time within 3 %.

    The ratio was 26 % low: ratio, time and stiffness trade off along the tail the holds
    see, and the model's error at the move's end decided.
    """
    config, data, arm, truth, _ = quiet_step_and_hold
    problem = Problem(data, arm, reading_of(config), 0.01)
    names = ["surface_y_mm", "stiffness_n_per_mm", "stiffening_exponent",
             "relaxation_ratio", "relaxation_time_s"]
    x, _ = problem.solve(names, truth)
    found = dict(zip(names, x.tolist(), strict=True))
    for name in ("relaxation_ratio", "relaxation_time_s"):
        assert found[name] == pytest.approx(truth[name], rel=0.03), name


def test_the_force_moving_within_a_burst_is_the_models(
        quiet_step_and_hold: tuple[Any, ...]) -> None:
    """On a quiet cell a burst's spread is the force's own motion: the model's, within 25 %.

    (Its variance, less a count's quantisation, ``q^2 / 12``.)

    The bursts right after a step see the foam relax (0.32 in 0.25 s) and the lag's last
    approach: read as noise, they put the noise 2-10 % high on relaxing hidden cells.
    """
    config, data, arm, truth, holds = quiet_step_and_hold
    signal = within_burst_variance(data, SpongeParams.unchecked(truth), arm, reading_of(config))
    quantum = 200.0 / 16384  # one count of the JR3's Fy at its 200 N full scale
    moving = holds & data.has_burst & (data.std_n > quantum)
    assert moving.sum() >= 5
    seen = data.std_n[moving] ** 2 - quantum**2 / 12
    assert np.all(np.abs(np.log(signal[moving] / seen)) < np.log(1.25))
    still = holds & data.has_burst & (data.std_n < quantum / 4)
    assert np.all(signal[still] < quantum**2 / 4)
