"""Open a cell as its config says: real devices, or the built-in emulators behind real drivers.

The robot's and the sensor's kinds (:mod:`forcelearn.site.kinds`) say how each
opens. An emulated device's far end is an :class:`EmulatedCell` in this
process (``in_process=True``), on one :class:`CellPhysics` with the sponge; the
drivers then connect to it exactly as they would to the devices (pyserial
opens the controller as ``forcelearn-robot://NAME``, python-can the JR3's bus
as ``can.Bus(interface="forcelearn-jr3", channel=NAME)``, the EGM driver takes
the in-process controller's socket-like end, the Net F/T driver its loopback
ports). ``forcelearn emulate`` serves the same cell to another process. The
trainer gets the same :class:`~forcelearn.cell.Cell` either way.

``CellSession.emulator_state()`` / ``load_emulator_state()`` checkpoint what a
bit-identical resume needs: the simulated clock, the arm, the sponge, and each
emulated device's state under its kind's name.

When the config names a calibration file (``[calibration] file``), it is read
before any device opens and the cell is built with it (R of its filter,
bias and tool gravity off every sample). If the sensor zeroes on opening, the
bias is re-derived for the zeroing pose
(:meth:`~forcelearn.calibration.Calibration.rezeroed`).

Example::

    from forcelearn.site import CellSession, load_cell_config

    with CellSession(load_cell_config("site.toml")) as session:
        print(session.cell.measure_force_n())
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from forcelearn.calibration import Calibration, load_calibration
from forcelearn.cell import Cell
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.part_foam import PartFoam
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.filtering import make_force_filter
from forcelearn.press_guard import DriftCheck, drift_rate_bound_n_per_s
from forcelearn.site.calibration_identity import check_identity
from forcelearn.site.config import CellConfig
from forcelearn.site.emulated_cell import EmulatedCell

log = logging.getLogger(__name__)


class CellSession:
    """The devices of one cell, opened together and closed together (a context manager).

    Args:
        config: the cell configuration.
        seed: seed of the emulated sensor's noise (ignored on a real cell).
        routes: emulated devices only: kind name -> that kind's own route options
            (``{"egm": EgmRoute("udp")}``; a kind absent takes its defaults).
    """

    def __init__(self, config: CellConfig, seed: int = 0,
                 routes: Mapping[str, object] | None = None):
        self.config = config
        self.emulated_cell: EmulatedCell | None = None
        """The far ends of the emulated devices (None on a real cell)."""
        self.physics: CellPhysics | None = None
        self.sponge: Sponge | PartFoam | None = None
        self.robot: Any = None
        """The robot driver of the config's robot kind."""
        self.sensor: Any = None
        """The sensor driver of the config's sensor kind."""
        self.cell: Cell | None = None
        self._stack = contextlib.ExitStack()
        try:
            self._open(seed, routes or {})
        except BaseException:
            self.close()
            raise

    def _open(self, seed: int, routes: Mapping[str, object]) -> None:
        cfg = self.config
        calibration = load_calibration(cfg.calibration_file) if cfg.calibration_file else None
        if cfg.robot_emulated or cfg.sensor_emulated:
            self.emulated_cell = EmulatedCell(cfg, seed, in_process=True, routes=routes)
            self._stack.callback(self.emulated_cell.close)  # after the drivers
            self.sponge, self.physics = self.emulated_cell.sponge, self.emulated_cell.physics
        cell = self.emulated_cell
        # Order (and so the close order): the far ends first, then the drivers.
        self.robot = cfg.robot_device.open(cfg, cell.robot if cell else None, self._stack)
        self.sensor = cfg.sensor_device.open(cfg, cell.sensor if cell else None, self._stack)
        if calibration is not None:
            calibration = self._calibration_for_this_zero(calibration)
        self.cell = Cell(
            self.robot,
            self.sensor,
            make_force_filter(cfg.filter),
            max_force_n=cfg.safety.max_force_n,
            # as many samples as the sensor delivers in the window (a JR3: one per ms)
            samples_per_step=cfg.task.samples_for(
                getattr(self.sensor, "sample_period_s", cfg.filter.sample_period_s)
            ),
            move_timeout_s=cfg.safety.move_timeout_s,
            # in the ideal profile nothing takes time, so there is nothing to dwell for
            settle_s=0.0 if cfg.robot_emulated and cfg.emulator.ideal else cfg.task.settle_s,
            calibration=calibration,
        )
        if calibration is not None:
            log.info("calibration %s applied: R = %.4g, tool %.3f kg", cfg.calibration_file,
                     calibration.noise_variance(cfg.filter.axis), calibration.tool.mass_kg)

    def _calibration_for_this_zero(self, calibration: Calibration) -> Calibration:
        """The calibration for the sensor as it opened (zeroed just now, at this pose)."""
        cfg = self.config
        self._check_identity(calibration)
        if cfg.sensor.zero_on_init:
            calibration = calibration.rezeroed(self.robot.read_pose().quaternion)
        measured_at = calibration.sensor.cutoff_hz
        cutoff_hz = getattr(cfg.sensor, "cutoff_hz", None)  # a Net F/T filters in the box
        if measured_at and cutoff_hz is not None and abs(measured_at - cutoff_hz) > 0.01:
            log.warning(
                "the calibration measured the noise at a %.2f Hz cut-off, the sensor "
                "runs at %.2f Hz: R may be wrong; calibrate again",
                measured_at,
                cutoff_hz,
            )
        return calibration

    def _check_identity(self, calibration: Calibration) -> None:
        """Refuse a calibration file of another sensor (serial, node, full scales), by name."""
        cfg = self.config
        live = cfg.sensor_device.calibration_info(
            cfg, self.sensor, cfg.robot_device.calibration_name(self.robot), None,
            cfg.sensor_serial)
        check_identity(calibration, f"calibration file {str(cfg.calibration_file)!r}", live,
                       getattr(cfg.sensor, "node_id", None), cfg.sensor_serial)

    @property
    def calibration(self) -> Calibration | None:
        """The calibration in force (the cell's, re-derived at every tare), or None."""
        return self.cell.calibration if self.cell is not None else None

    @property
    def robot_emulator(self) -> Any:
        """The robot's emulator (robot controller, EGM controller), None if the robot is real."""
        cell = self.emulated_cell
        return cell.robot.emulator if cell is not None and cell.robot is not None else None

    @property
    def sensor_emulator(self) -> Any:
        """The sensor's emulator (JR3 node, Net F/T box), None if the sensor is real."""
        cell = self.emulated_cell
        return cell.sensor.emulator if cell is not None and cell.sensor is not None else None

    @property
    def emulated(self) -> bool:
        """True when any device is emulated."""
        return self.emulated_cell is not None

    def emulator_state(self) -> dict[str, Any]:
        """What the emulators must restore for a bit-identical resume (JSON-able).

        With them, the cell's own zero (the zero checks' software part) and its press
        guard's last reading, which go with the emulated sensor's restored offsets.
        """
        if self.emulated_cell is None:
            return {}
        state: dict[str, Any] = self.emulated_cell.state_dict()
        cell = self.cell
        if cell is not None:
            guard = cell.press_guard
            state["cell"] = {
                "zero_residual": [float(v) for v in cell.zero_residual],
                "zero_std_n": cell.zero_std_n, "zero_time_s": cell.zero_time_s,
                "guard": None if guard is None else guard.state_dict(),
                "drift_checks": [dataclasses.asdict(c) for c in cell.drift_checks],
            }
        return state

    def load_emulator_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`emulator_state` (after the drivers' initialisation)."""
        if self.emulated_cell is None:
            return
        own = state.get("cell")
        self.emulated_cell.load_state_dict({k: v for k, v in state.items() if k != "cell"})
        cell = self.cell
        if own is not None and cell is not None:
            cell.zero_residual = np.asarray(own["zero_residual"], dtype=float)
            cell.zero_std_n, cell.zero_time_s = own["zero_std_n"], own["zero_time_s"]
            # the drift the run measured goes on (older checkpoints: none measured)
            cell.drift_checks = [DriftCheck(**c) for c in own.get("drift_checks", [])]
            cell.drift_rate_n_per_s = drift_rate_bound_n_per_s(cell.drift_checks)
            if own["guard"] is not None and cell.press_guard is not None:
                cell.press_guard.load_state_dict(own["guard"])

    def close(self) -> None:
        """Stop the robot, release the devices, stop the emulators; safe to call twice."""
        self._stack.close()

    def __enter__(self) -> CellSession:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
