"""A damaged RDT record numbered past its request is not a sample (the driver's guard)."""

from __future__ import annotations

import dataclasses

import numpy as np
from netft_support import config_for, start

from forcelearn.drivers.netft import NetFtSensor
from forcelearn.drivers.netft.driver import SEQUENCE_BEYOND_REQUEST
from forcelearn.emulators.netft.in_process import InProcessRdtSocket
from forcelearn.protocols.netft import Record

HUGE_COUNTS = (2_000_000_000,) * 6


def _damaged(records: list[Record]) -> list[Record]:
    """Record 4 of a request of 10 replaced by damage: a sequence far past 10, huge counts."""
    if len(records) != 10:
        return records
    out = list(records)
    out[3] = dataclasses.replace(out[3], rdt_sequence=875_519_242, counts=HUGE_COUNTS)
    return out


def test_a_record_numbered_past_its_request_is_rejected_not_read() -> None:
    """The burst's samples are the box's own; the damaged record is counted as rejected."""
    with start(seed=5, records_hook=_damaged) as emu, \
            NetFtSensor(config_for(emu), sock=InProcessRdtSocket(emu)) as sensor:
        samples = sensor.read_many(10, window=10)
        forces = np.array([s.wrench[:3] for s in samples])
        assert np.all(np.abs(forces) < 1000.0)  # no sample of the damage's counts
        assert sensor.stats.rejected[SEQUENCE_BEYOND_REQUEST] == 1
