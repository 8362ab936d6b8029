"""A Net F/T reboot whose new sample count lands past the old one is seen by the host's clock."""

from __future__ import annotations

import pytest
from netft_support import config_for, start

from forcelearn.drivers.netft import NetFtSensor
from forcelearn.drivers.netft.uptime import INTERNAL_RATE_HZ, UptimeCheck
from forcelearn.emulators.netft import NetFtEmulator
from forcelearn.errors import SensorRebooted

RATE = INTERNAL_RATE_HZ


def test_a_count_younger_than_the_wait_is_a_restart() -> None:
    """Up 0.1 s, read; 2 s later the box (rebooted at 1 s) counts 1 s: past the old count."""
    check = UptimeCheck()
    assert not check.restarted(int(0.1 * RATE), 0.1, 0.1)
    assert check.restarted(int(1.0 * RATE), 2.0, 2.0)
    assert check.restarts == 1


def test_a_count_that_kept_pace_is_not() -> None:
    """Records spaced as the clock says, or read before the reference (streaming): no restart."""
    check = UptimeCheck()
    for t in (0.1, 0.5, 2.0, 30.0):
        assert not check.restarted(round(t * RATE), t, t)
    assert not check.restarted(round(29.0 * RATE), 29.0, 30.5)  # sampled before the reference
    assert check.restarts == 0


def test_a_reboot_after_the_bias_before_any_record() -> None:
    """Biased at 5 s; a record asked for at 6 s counting 0.5 s of uptime: the bias is gone."""
    check = UptimeCheck()
    check.note_bias(5.0)
    assert check.restarted(int(0.5 * RATE), 6.0, 6.0)
    check.forget()
    check.note_bias(5.0)
    assert not check.restarted(int(100.0 * RATE), 6.0, 6.0)


def read_after(emulator: NetFtEmulator, sensor: NetFtSensor, reboot: bool) -> None:
    """Read early, wait 1 s of the box's clock, reboot it (or not), wait 0.5 s, read."""
    sensor.read_many(3)
    emulator.clock.advance(1.0)
    if reboot:
        emulator.inject_reboot()
    emulator.clock.advance(0.5)
    sensor.read_many(3)


@pytest.mark.parametrize("reboot", [True, False])
def test_the_driver_sees_a_reboot_the_sequence_misses(reboot: bool) -> None:
    """ft_sequence after the reboot (0.5 s) is past the one before (3 records): no going back."""
    with start() as emulator, NetFtSensor(
        config_for(emulator), clock=lambda: emulator.clock.now_s
    ) as sensor:
        if not reboot:
            read_after(emulator, sensor, reboot)
            assert sensor.stats.reboots == 0
            return
        with pytest.raises(SensorRebooted, match="rebooted"):
            read_after(emulator, sensor, reboot)
        assert emulator.ft_sequence > 3  # the count did not go back
        assert sensor.stats.reboots == 1
