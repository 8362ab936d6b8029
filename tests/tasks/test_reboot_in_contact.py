"""A sensor that reboots while the tool presses never yields a wrong reading.

Found on the default emulated cell: after a JR3 bootup in contact, reading again
(as the error said) re-zeroed the sensor there, and the cell read 10.5, 7.0, 5.2 N
where 21 N pressed. Now the driver reports the reboot until the cell retracts to
free space and re-zeroes; pressed again, it reads the true force.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from forcelearn.devices import Pose
from forcelearn.errors import SensorStale
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.surface import SurfaceTask

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
READS_AFTER_REBOOT = 3


def _true_normal_n(session: CellSession) -> float:
    """The contact force the emulated sponge exerts now (N, +Y): the truth, not a reading."""
    physics = session.physics
    assert physics is not None
    return float(physics.environment.contact_force_world_n(physics.pose.position_mm)[1])


@pytest.mark.parametrize("example", [None, "netft-cell.toml"])
def test_a_sensor_reboot_in_contact_never_yields_a_reading_3_sigma_off(
    example: str | None,
) -> None:
    """Press to about the desired force, reboot the sensor, and go on as a run would."""
    config = load_cell_config(EXAMPLES / example if example else None)
    with CellSession(config, seed=1) as session:
        cell, emulator = session.cell, session.sensor_emulator
        assert cell is not None
        sigma_n = emulator.model.params.noise_std[cell.force_filter.config.axis]
        task = SurfaceTask(cell, config.task, config.safety.max_step_mm)
        task.reset()
        start = cell.pose
        press = Pose(start.x_mm, start.y_mm - 2.0, start.z_mm, start.quaternion)
        cell.move_in_steps(press, config.safety.max_step_mm, guard_force=True)
        assert _true_normal_n(session) > 0.5 * config.task.desired_force_n  # in contact

        def check_reading() -> bool:
            """Read once; a reading must be within 3 sigma of the truth. False: refused."""
            cell.reset_filter()
            try:
                reading = cell.measure_force_n()
            except SensorStale:  # a reboot is reported, never read through
                return False
            assert abs(reading - _true_normal_n(session)) <= 3 * sigma_n
            return True

        assert check_reading()
        if example is None:
            emulator.inject_bootup()
        else:
            emulator.inject_reboot()
        refused = [not check_reading() for _ in range(READS_AFTER_REBOOT)]
        assert all(refused)  # until the cell has left the part, nothing is read

        from forcelearn.tasks.recovery import retract_and_retare

        recovered = retract_and_retare(cell, config.task.retract_y_mm, config.safety.max_step_mm)
        assert recovered.retract_pose.y_mm == config.task.retract_y_mm
        assert _true_normal_n(session) == 0.0  # the zero was taken in free space
        cell.move_in_steps(press, config.safety.max_step_mm, guard_force=True)
        assert all(check_reading() for _ in range(READS_AFTER_REBOOT))
