"""The zero check closing a trial: a moved zero voids it, one outlier of the noise does not."""

from __future__ import annotations

from pathlib import Path

import pytest

from forcelearn.devices import Pose
from forcelearn.errors import ZeroMoved
from forcelearn.tools.experiments.fault_recovery import RunRecovery

BOUND_N = 0.5


class Checks:
    """A cell in free space whose zero checks read the given forces, one per check."""

    def __init__(self, readings: list[float]) -> None:
        self.readings = readings
        self.pose = Pose(0.0, 20.0, 0.0)
        self.stops = 0
        self.checks = 0

    def check_zero(self, bound_n: object) -> tuple[float, float]:
        """The next reading against a fixed bound."""
        self.checks += 1
        return self.readings.pop(0), BOUND_N

    def stop(self) -> None:
        """Count the stops."""
        self.stops += 1


def recovery(cell: Checks, tmp_path: Path) -> RunRecovery:
    """The run's recovery over ``cell``, the zero check on."""
    return RunRecovery(tmp_path, cell, retract_y_mm=10.0, max_step_mm=5.0,  # type: ignore[arg-type]
                       zero_check=True)


def test_one_outlier_beyond_the_bound_is_read_again_and_voids_nothing(tmp_path: Path) -> None:
    """A check over the bound, then one within: the trial stands."""
    cell = Checks([1.2 * BOUND_N, 0.1 * BOUND_N])
    recovery(cell, tmp_path).check_zero(3)
    assert cell.checks == 2 and cell.stops == 0


def test_a_zero_that_moved_reads_so_twice_and_voids_the_trial(tmp_path: Path) -> None:
    """Two checks over the bound: ZeroMoved, the robot stopped."""
    cell = Checks([3.0 * BOUND_N, 3.0 * BOUND_N])
    with pytest.raises(ZeroMoved, match="trial 3"):
        recovery(cell, tmp_path).check_zero(3)
    assert cell.checks == 2 and cell.stops == 1
