"""The stuck monitor and the end verdict, on made-up trials (pure)."""

from __future__ import annotations

from forcelearn.tasks.surface_diagnosis import StuckMonitor, diagnose
from forcelearn.trainer import TrialRecord


def _record(index: int, failed: bool, steps: int = 20) -> TrialRecord:
    return TrialRecord(
        index=index, phase="generalized", steps=steps, failed=failed, force_rms_n=1.0,
        mean_r=0.5, start_force_n=5.0, cell_time_s=10.0,
    )


def test_commands_at_the_deep_end_warn_once_naming_the_keys() -> None:
    """Commands at the deep end warn once naming the keys."""
    monitor = StuckMonitor(centre_y_mm=-4.0, max_offset_mm=15.0, steps_per_trial=20, edge_trials=5)
    warnings = [monitor.update(_record(i, False), [-19.0] * 15 + [-10.0] * 5) for i in range(8)]
    assert warnings[:4] == [None] * 4
    assert warnings[4] is not None and warnings[5:] == [None] * 3
    assert "deep end" in warnings[4] and "task.max_offset_mm" in warnings[4]
    converged, text = diagnose([_record(i, False) for i in range(8)], None, monitor)
    assert not converged and "task.max_offset_mm" in (text or "")


def test_commands_inside_the_range_do_not_warn() -> None:
    """Commands inside the range do not warn."""
    monitor = StuckMonitor(-4.0, 15.0, 20, edge_trials=5)
    assert all(monitor.update(_record(i, False), [-18.0] * 20) is None for i in range(20))


def test_a_long_run_of_failures_warns() -> None:
    """A long run of failures warns."""
    monitor = StuckMonitor(-4.0, 15.0, 20, stall_trials=10)
    warnings = [monitor.update(_record(i, True, steps=3), [-5.0] * 3) for i in range(12)]
    assert warnings[9] is not None and "no trial completed" in warnings[9]
    assert sum(w is not None for w in warnings) == 1


def test_a_converged_run_has_no_diagnosis() -> None:
    """A converged run has no diagnosis."""
    monitor = StuckMonitor(-4.0, 15.0, 20)
    assert diagnose([_record(0, False)], 0, monitor) == (True, None)


def test_the_edges_move_with_the_maps_wear_shift() -> None:
    """A followed map's range moves with its wear shift: the edge is centre + shift ± range.

    Commands 3 mm under the path sit at the deep edge of a map that has not
    shifted, and at the centre of one that has followed the sponge 3 mm down.
    """
    path = tuple(-4.0 - 0.1 * k for k in range(20))
    commands = [y - 3.0 for y in path]
    unshifted = StuckMonitor(-4.0, 3.0, 20, path_y_mm=path, edge_trials=5)
    assert [unshifted.update(_record(i, False), commands) for i in range(5)][4] is not None
    shifted = StuckMonitor(-4.0, 3.0, 20, path_y_mm=path, edge_trials=5)
    assert all(shifted.update(_record(i, False), commands, -3.0) is None for i in range(20))
    deep = [y - 6.0 for y in commands]  # 3 mm under the shifted centre: its deep edge
    warnings = [shifted.update(_record(i, False), deep, -3.0) for i in range(5)]
    assert warnings[4] is not None and "deep end" in warnings[4]
