"""Is this calibration file of this cell's sensor? Serial, node and full scales, by name.

A calibration holds for one sensor: another sensor's bias, noise and even
tool fit say nothing of this one. When a session opens with a calibration
file, :func:`check_identity` compares what the file records with what the cell
says of its sensor and refuses the file (:class:`~forcelearn.errors.ConfigError`
naming the file, the key and both values) when:

* ``[calibration] sensor_serial`` is set and the file's ``sensor.serial`` is
  another (a file without a serial is accepted with a warning: it cannot tell);
* the sensor has a CAN node id (JR3) and the file's ``sensor.node_id`` is another;
* both full-scale sets are known and differ by more than 1 % on an axis
  (another sensor, or the same one in another range).
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from forcelearn.calibration import Calibration, SensorInfo
from forcelearn.errors import ConfigError

log = logging.getLogger(__name__)

FULL_SCALE_TOLERANCE = 0.01
"""Relative difference of a full scale beyond which the file is of another sensor or range."""


def load_sensor_serial(table: dict[str, Any]) -> str:
    """``[calibration] sensor_serial`` ("" when not given)."""
    serial = table.get("sensor_serial", "")
    if not isinstance(serial, str):
        raise ConfigError(f"calibration.sensor_serial = {serial!r}: a string (the label on the "
                          "sensor)")
    return serial


def check_identity(cal: Calibration, source: str, live: SensorInfo, node_id: int | None,
                   serial: str) -> None:
    """Refuse a calibration of another sensor (module docstring); ConfigError names the key."""
    advice = ("the file is of another sensor: point [calibration] file at this sensor's own, "
              "or run `forcelearn calibrate` on it")
    recorded = cal.sensor
    if serial and recorded.serial and recorded.serial != serial:
        raise ConfigError(f"{source}: sensor.serial = {recorded.serial!r} but this cell's sensor "
                          f"is [calibration] sensor_serial = {serial!r}: {advice}")
    if serial and not recorded.serial:
        log.warning("%s records no sensor serial: cannot check it is of sensor %r "
                    "(calibrate with --sensor-serial)", source, serial)
    if node_id is not None and recorded.node_id != node_id:
        raise ConfigError(f"{source}: sensor.node_id = {recorded.node_id} but this cell's sensor "
                          f"is node {node_id} ([sensor] node_id): {advice}")
    mine, theirs = np.asarray(live.full_scales, float), np.asarray(recorded.full_scales, float)
    if np.all(mine > 0) and np.all(theirs > 0):
        off = np.abs(theirs / mine - 1.0) > FULL_SCALE_TOLERANCE
        if np.any(off):
            raise ConfigError(f"{source}: sensor.full_scales = {theirs.tolist()} but this cell's "
                              f"sensor reports {mine.tolist()}: {advice}")
