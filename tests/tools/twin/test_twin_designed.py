"""An identification plan designed from a twin's uncertainties."""

from __future__ import annotations

import dataclasses
from typing import Any

from forcelearn.tools.twin.designed import TARGET_SHARE, design, relaxation_sigmas
from forcelearn.tools.twin.identify import IdentifyPlan


def _twin(loose: set[str], member: str = "linear") -> dict[str, Any]:
    values = {"stiffness_n_per_mm": 2.0, "relaxation_ratio": 0.4, "relaxation_time_s": 0.5,
              "start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
              "lag_s": 0.03, "noise_std": 0.2, "bias_drift_per_sqrt_s": 0.02}
    return {"member": member, "parameters": [
        {"name": n, "value": v, "sigma": 1.0 if n in loose else 0.0, "determined": n not in loose}
        for n, v in values.items()]}


def test_only_what_the_twin_lacks_is_planned() -> None:
    """Relaxation loose, the rest determined: holds (and the cycles' short ones), no grid."""
    designed = design(_twin({"relaxation_time_s"}), desired_force_n=7.0)
    assert designed.plan.hold_steps >= 2
    assert len(designed.plan.lengths_mm) == 1 and len(designed.plan.speeds_mm_s) == 1
    assert designed.plan.cycles == IdentifyPlan().cycles  # each step in and out a relaxation
    assert set(designed.expected) == {"relaxation_ratio", "relaxation_time_s"}
    full = IdentifyPlan()
    assert designed.plan.cell_time_s() < full.cell_time_s()


def test_the_arm_loose_plans_the_polled_moves_with_an_expected_sigma() -> None:
    """Lag loose: the grid of lengths x speeds, and a finite expected 1-sigma for it."""
    designed = design(_twin({"lag_s"}), desired_force_n=7.0)
    assert len(designed.plan.lengths_mm) > 1 and len(designed.plan.speeds_mm_s) > 1
    value, sigma = designed.expected["lag_s"]
    assert 0 < sigma < value


def test_more_holds_expect_a_smaller_sigma() -> None:
    """The relaxation's expected 1-sigma falls as holds are added (the design's lever)."""
    plan = IdentifyPlan()
    few = relaxation_sigmas(0.4, 0.5, 3.0, 0.3, dataclasses.replace(plan, hold_steps=2))
    many = relaxation_sigmas(0.4, 0.5, 3.0, 0.3, dataclasses.replace(plan, hold_steps=8))
    assert many["relaxation_time_s"] < few["relaxation_time_s"]
    assert many["relaxation_ratio"] < few["relaxation_ratio"]
    designed = design(_twin({"relaxation_ratio", "relaxation_time_s"}), desired_force_n=7.0)
    ratio, sigma = designed.expected["relaxation_ratio"]
    assert sigma <= TARGET_SHARE * ratio


def test_the_holds_last_six_of_the_twins_time_constants_when_it_has_one() -> None:
    """A time known to half its size sets the holds; an unknown one, the slowest foam's 1 s."""
    twin = _twin({"relaxation_ratio", "relaxation_time_s"})
    for row in twin["parameters"]:
        if row["name"] == "relaxation_time_s":
            row["sigma"] = 0.05  # 0.5 +- 0.05 s: loose to 3 %, known to 10 %
    assert max(design(twin, 7.0).plan.hold_s) == 6 * 0.5
    assert max(design(_twin({"relaxation_time_s"}), 7.0).plan.hold_s) == 6 * 1.0


def test_a_slow_step_expects_a_larger_sigma() -> None:
    """What relaxes while the arm moves is not seen: a later first burst, a looser ratio.

    A 3 mm step takes 0.2-0.6 s to come in position on the hidden cells; on a 0.25 s foam
    the holds see only the tail, and the ratio and time trade off along it.
    """
    plan = IdentifyPlan()
    soon = relaxation_sigmas(0.3, 0.25, 6.0, 0.3, plan, delay_s=0.1)
    late = relaxation_sigmas(0.3, 0.25, 6.0, 0.3, plan, delay_s=0.5)
    assert late["relaxation_ratio"] > 2 * soon["relaxation_ratio"]



def test_pose_reads_expect_the_acceleration_determined_in_one_pass() -> None:
    """The timed moves' pose reads: acceleration within 3 % from one pass over the grid.

    Without them the 44 ms in-position windows leave it at 12 % (four passes still 6 %).
    """
    from forcelearn.tools.twin.designed import arm_sigmas

    arm = {"start_delay_s": 0.12, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
           "lag_s": 0.019}
    plan = IdentifyPlan()
    read = arm_sigmas(arm, plan)["accel_mm_s2"]
    polled = arm_sigmas(arm, dataclasses.replace(plan, read_positions=False))["accel_mm_s2"]
    assert read <= 0.03 * arm["accel_mm_s2"] < polled
    designed = design(_twin({"accel_mm_s2"}), desired_force_n=7.0)
    assert designed.plan.repeats == 1
    assert designed.expected["accel_mm_s2"][1] <= TARGET_SHARE * 1000.0
