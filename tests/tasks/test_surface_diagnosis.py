"""The stuck monitor and the end verdict, on made-up trials (pure)."""

from __future__ import annotations

from forcelearn.tasks.surface_diagnosis import StuckMonitor, diagnose
from forcelearn.trainer import TrialRecord

DESIRED_N = 19.6133
BAND_N = 0.05 * DESIRED_N


def _record(index: int, failed: bool, steps: int = 20, rms: float = 1.0) -> TrialRecord:
    return TrialRecord(
        index=index, phase="generalized", steps=steps, failed=failed, force_rms_n=rms,
        mean_r=0.5, start_force_n=5.0, cell_time_s=10.0,
    )


def test_commands_at_the_deep_end_warn_once_naming_the_keys() -> None:
    """Commands at the deep end warn once naming the keys."""
    monitor = StuckMonitor(centre_y_mm=-4.0, max_offset_mm=15.0, steps_per_trial=20, edge_trials=5,
                           source="config")
    warnings = [monitor.update(_record(i, False), [-19.0] * 15 + [-10.0] * 5) for i in range(8)]
    assert warnings[:4] == [None] * 4
    assert warnings[4] is not None and warnings[5:] == [None] * 3
    assert "deep end" in warnings[4] and "task.max_offset_mm" in warnings[4]
    verdict = diagnose([_record(i, False) for i in range(8)], None, monitor, DESIRED_N)
    assert not verdict["converged"] and "task.max_offset_mm" in (verdict["diagnosis"] or "")


def test_the_edge_advice_fits_the_maps_source() -> None:
    """The probe chose the map: never 'remove them so the probe chooses'; configured: do say so."""
    texts = {}
    for source in ("probe", "config", "probe+config", "fallback"):
        monitor = StuckMonitor(-4.0, 15.0, 20, edge_trials=3, source=source)
        warnings = [monitor.update(_record(i, False), [-19.0] * 20) for i in range(3)]
        assert warnings[2] is not None
        texts[source] = warnings[2]
    assert "remove" not in texts["probe"] and "probe.max_depth_mm" in texts["probe"]
    assert "so the surface probe chooses" in texts["config"]
    assert "override the probe" in texts["probe+config"]
    assert "[probe] enabled = true" in texts["fallback"]


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


def test_a_run_that_converged_and_ended_in_band_has_no_diagnosis() -> None:
    """Converged and in band over its last 10 trials: no diagnosis, nothing out of band."""
    monitor = StuckMonitor(-4.0, 15.0, 20)
    records = [_record(i, False, rms=0.5) for i in range(30)]
    verdict = diagnose(records, 0, monitor, DESIRED_N)
    assert verdict == {
        "converged": True, "in_band_at_end": True,
        "trials_out_of_band_after_convergence": 0, "diagnosis": None,
    }


def test_a_run_that_converged_then_left_the_band_says_so() -> None:
    """Converged at 0, then 20 trials at 5 N RMS: not in band at the end, counted, diagnosed."""
    monitor = StuckMonitor(-4.0, 15.0, 20)
    records = [_record(i, False, rms=0.5) for i in range(20)]
    records += [_record(i, False, rms=5.0) for i in range(20, 40)]
    verdict = diagnose(records, 0, monitor, DESIRED_N)
    assert verdict["converged"] is True
    assert verdict["in_band_at_end"] is False
    assert verdict["trials_out_of_band_after_convergence"] == 20
    assert "did not end in band" in verdict["diagnosis"]
    assert f"{BAND_N:.2f} N" in verdict["diagnosis"]


def test_a_failed_trial_at_the_end_is_not_in_band() -> None:
    """One failed trial among the last 10: not in band at the end, though the median is."""
    monitor = StuckMonitor(-4.0, 15.0, 20)
    records = [_record(i, False, rms=0.5) for i in range(29)] + [_record(29, True, steps=5)]
    verdict = diagnose(records, 0, monitor, DESIRED_N)
    assert verdict["in_band_at_end"] is False and verdict["diagnosis"]


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
