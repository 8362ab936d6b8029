"""A small slice of the fault-in-contact campaign (the whole one: docs/fuzzing.md)."""

from __future__ import annotations

from pathlib import Path

from forcelearn.tools.fuzz.fault_campaign import cell_config, fault_free_run, one_run

FAULTS_PER_DEVICE = 5


def test_faults_at_random_instants_never_press_too_hard_zero_in_contact_or_lose_trials(
    tmp_path: Path,
) -> None:
    """One short run with faults on both devices and a kill, resumed until it completes."""
    cell, seed = "link+jr3", 11
    config = cell_config(cell, tmp_path, trials=2, steps=4, probe=False)
    ticks, worst_n, _ = fault_free_run(config, tmp_path / "free", seed)
    report = one_run(cell, config, tmp_path / "run", seed, ticks, FAULTS_PER_DEVICE, 1,
                     max(1.0, 2 * worst_n))
    assert sum(report.fired.values()) == 2 * FAULTS_PER_DEVICE + 1
    assert report.finished, report.problems
    assert report.over_limit == 0 and report.zeros_in_contact == 0
    assert report.lost_or_duplicated == 0 and report.untyped_ends == 0, report.problems
    assert report.late_stops == 0, report.problems
    assert not report.bad_readings and report.readings > 0  # every used reading was true
