"""The §4 task: eq. (4), failure and return to start, and a short learning run."""

import numpy as np
import pytest

from forcelearn.emulators.physics.two_link_arm import ContourGeometry, TwoLinkContourCell
from forcelearn.learning import SRVLearner, SRVParams
from forcelearn.tasks.contour import ContourTask, ContourTaskSpec, evaluation
from forcelearn.trainer import converged_trial, run_trial, train


def make_task() -> ContourTask:
    """The default §4 task on the default cell."""
    return ContourTask(TwoLinkContourCell(), ContourTaskSpec())


def test_eq4_weights_force_by_2_newton_and_velocity_by_2_cm() -> None:
    """R = |ΔF|/2 N + |Δv|/2 cm: 0.5 N and 0.4 cm errors give 0.25 + 0.2."""
    spec = ContourTaskSpec()
    assert evaluation(spec, 0.5, -0.004) == pytest.approx(0.45)
    assert evaluation(spec, -2.0, 0.0) == pytest.approx(1.0)
    assert evaluation(spec, 0.0, 0.02) == pytest.approx(1.0)


def test_standing_still_is_evaluated_from_force_and_lost_progress() -> None:
    """A zero step keeps 0.7212 N and makes no progress: r = 0.2788/2 + 1/2."""
    task = make_task()
    x = task.reset()
    outcome = task.step(x.copy())
    assert outcome.force_n == pytest.approx(0.7212)
    assert outcome.extras["velocity_error_m"] == pytest.approx(-0.01)
    assert outcome.r == pytest.approx(0.2788 / 2 + 0.5)
    assert not outcome.failed


def test_a_step_along_the_contour_is_a_near_perfect_step() -> None:
    """Commanding the IK of the next 1 N contour point 1 cm on gives r close to 0."""
    from forcelearn.emulators.physics.two_link_arm import inverse_kinematics

    task = make_task()
    task.reset()
    g = task.cell.geometry
    radius = g.radius_m - 0.01
    angle = np.radians(g.normal_angle_deg) + 0.01 / radius
    target = inverse_kinematics(
        g, g.centre_m[0] + radius * np.cos(angle), g.centre_m[1] + radius * np.sin(angle)
    )
    outcome = task.step(np.array(target))
    assert outcome.force_error_n == pytest.approx(0.0, abs=1e-9)
    assert outcome.r == pytest.approx(0.0, abs=0.01)  # velocity: start was 7.212 mm deep


def test_pushing_hard_fails_and_the_next_trial_starts_from_the_start_pose() -> None:
    """R > 1 is a failure; reset returns the arm to (45°, −45°)."""
    task = make_task()
    task.reset()
    outcome = task.step(np.array([44.0, -45.0]))  # about 2.6 cm into the surface
    assert outcome.r > 1.0 and outcome.failed
    assert tuple(task.reset()) == (45.0, -45.0)
    assert task.start_force_n == pytest.approx(0.7212)


def test_leaving_the_partition_is_a_failure() -> None:
    """A reached pose outside the joint ranges fails even if r were small."""
    task = ContourTask(TwoLinkContourCell(), ContourTaskSpec(theta1_range_deg=(44.0, 45.5)))
    task.reset()
    assert task.step(np.array([45.6, -45.0])).failed


def test_trial_stops_at_the_failing_step_and_counts_completed_steps() -> None:
    """A learner whose actions push into the surface fails on step 1 with 0 steps done."""
    task = make_task()
    learner = SRVLearner(
        task.grid, 2, SRVParams(initial_mean=-5.0), rng=0, output=task.output_map()
    )
    record, log = run_trial(learner, task, 0)
    assert record.failed and record.steps == 0 and len(log.rows) == 1


def test_convergence_needs_ten_complete_trials_within_five_percent() -> None:
    """Crafted table: the first window of 10 good trials starts at index 5."""
    from forcelearn.trainer import TrialRecord

    def rec(i: int, steps: int = 45, rms: float = 0.01, failed: bool = False) -> TrialRecord:
        return TrialRecord(i, "specialized", steps, failed, 0.1, rms, 0.7)

    rows = [rec(0), rec(1, rms=0.051), rec(2), rec(3, steps=44, failed=True), rec(4, rms=0.2)]
    rows += [rec(i) for i in range(5, 15)]
    assert converged_trial(rows, 45, 1.0) == 5
    assert converged_trial(rows[:14], 45, 1.0) is None  # only 9 good in a row
    rows[9] = rec(9, rms=0.0500001)
    assert converged_trial(rows, 45, 1.0) is None
    rows[9] = rec(9, rms=0.05)  # exactly at the band counts as inside
    assert converged_trial(rows, 45, 1.0) == 5


@pytest.mark.parametrize("seed", [0, 1])
def test_short_two_phase_run_reaches_the_global_criterion_and_improves(seed: int) -> None:
    """Within 500 trials the arm completes 10 paths in a row; later its force error is lower."""
    task = make_task()
    learner = SRVLearner(task.grid, 2, SRVParams(), rng=seed, output=task.output_map())
    result = train(learner, task, 500)
    assert result.switch_trial is not None
    tail = result.records[-50:]
    assert sum(r.steps == 45 and not r.failed for r in tail) >= 45  # exploration may still fail
    switch_rms = result.records[result.switch_trial].force_rms_n
    assert np.median([r.force_rms_n for r in tail]) < switch_rms


def test_same_seed_same_run_bit_for_bit() -> None:
    """Two runs with one seed produce identical trial tables and weights."""
    runs = []
    for _ in range(2):
        task = make_task()
        learner = SRVLearner(task.grid, 2, SRVParams(), rng=7, output=task.output_map())
        runs.append((train(learner, task, 60).records, learner.weights.copy()))
    assert runs[0][0] == runs[1][0]
    assert np.array_equal(runs[0][1], runs[1][1])


def test_geometry_with_lag_still_evaluates_consistently() -> None:
    """With a lagging servo the task reports the reached, not the commanded, angles."""
    task = ContourTask(TwoLinkContourCell(ContourGeometry(servo_lag=0.5)), ContourTaskSpec())
    task.reset()
    outcome = task.step(np.array([45.2, -45.2]))
    assert outcome.x == pytest.approx([45.1, -45.1])


def test_greedy_evaluation_leaves_the_learner_untouched() -> None:
    """learn=False acts with μ, draws no random numbers and changes no W or V."""
    task = make_task()
    learner = SRVLearner(task.grid, 2, SRVParams(), rng=5, output=task.output_map())
    train(learner, task, 20)
    weights, predictions = learner.weights.copy(), learner.predictions.copy()
    rng_state = learner.rng.bit_generator.state
    record, log = run_trial(learner, task, 20, learn=False)
    assert np.array_equal(weights, learner.weights)
    assert np.array_equal(predictions, learner.predictions)
    assert learner.rng.bit_generator.state == rng_state
    assert all(row["sigma"] > 0 for row in log.rows)
    assert record.steps <= 45


def test_global_criterion_is_found_on_records_whatever_the_phase() -> None:
    """criterion_trial finds the N-th success in a row, and equals the switch trial."""
    from forcelearn.trainer import TrialRecord, criterion_trial

    fails = {2, 5, 13}
    rows = [TrialRecord(i, "specialized", 45, i in fails, 0.1, 0.1, 0.7) for i in range(30)]
    assert criterion_trial(rows, 10) == 23  # successes 14..23
    assert criterion_trial(rows[:23], 10) is None
    task = make_task()
    learner = SRVLearner(task.grid, 2, SRVParams(), rng=0, output=task.output_map())
    result = train(learner, task, 400)
    assert criterion_trial(result.records, 10) == result.switch_trial
