"""Open a cell as its config says: real devices, or the built-in emulators behind real drivers.

An emulated cell starts, in this process, the robot-controller emulator (or,
with ``[robot] kind = "egm"``, the EGM controller emulator, in process) and
the JR3 emulator (or, with ``[sensor] kind = "netft"``, the Net F/T emulator on
loopback), all reading one :class:`CellPhysics` with the sponge
(:mod:`.device_factory` opens the Ethernet kinds); the drivers then connect to
them exactly as they would to the devices: pyserial opens the controller as
``forcelearn-robot://NAME`` and python-can the JR3's bus as
``can.Bus(interface="forcelearn-jr3", channel=NAME)``, both in-process routes
that answer in the driver's thread (the same bytes as a pty and a CAN adapter,
without a thread hand-over per exchange; ``forcelearn emulate`` serves the pty
and slcan routes for another process). The EGM driver takes the in-process
controller's socket-like end in place of its UDP socket (``egm_route="udp"``
puts loopback UDP and the emulator's thread back, for comparison). The trainer
gets the same :class:`~forcelearn.cell.Cell` either way.

``CellSession.emulator_state()`` / ``load_emulator_state()`` checkpoint what a
bit-identical resume needs (the simulated clock, the arm's motion and the
link's wire timelines, sponge wear and relaxation, sensor noise generator,
filter state, bias, offsets, frame counter, the bus timeline).

When the config names a calibration file (``[calibration] file``), it is read
before any device opens; the Kalman filter takes R from the noise variance of
its axis, and the cell subtracts bias and tool gravity from every sample. If
the sensor zeroes on opening, the bias is re-derived for the zeroing pose
(:meth:`~forcelearn.calibration.Calibration.rezeroed`).
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import replace
from typing import Any

import can
from can.interfaces.slcan import slcanBus

from forcelearn.calibration import Calibration, load_calibration
from forcelearn.cell import Cell
from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import ComputerLinkRobot
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.robot_controller.server import RobotControllerEmulator
from forcelearn.errors import ForcelearnError, LinkError, SensorBusError
from forcelearn.filtering import make_force_filter
from forcelearn.site.config import CellConfig
from forcelearn.site.emulated_cell import (
    emulated_jr3,
    emulated_physics,
    emulated_robot,
    private_channel,
)
from forcelearn.site.ethernet import Opened, open_egm, open_netft

log = logging.getLogger(__name__)

SLCAN_VERSION_TIMEOUT_S = 2.0
"""Longest wait for the slcan adapter's version answer when opening it (s)."""
NETFT_SETTLE_TIMEOUT_S = 5.0
"""On resume, longest wait for the emulated Net F/T to take the driver's requests (s)."""


class CellSession:
    """The devices of one cell, opened together and closed together (a context manager).

    Args:
        config: the cell configuration.
        seed: seed of the emulated sensor's noise (ignored on a real cell).
        egm_route: emulated EGM only: ``"in_process"`` (default) or ``"udp"``.
    """

    def __init__(self, config: CellConfig, seed: int = 0, egm_route: str = "in_process"):
        self.config = config
        self.physics: CellPhysics | None = None
        self.sponge: Sponge | None = None
        self.robot_emulator: RobotControllerEmulator | None = None
        self.sensor_emulator: Jr3EmulatorNode | None = None
        self._bus: can.BusABC | None = None
        self.robot: Any = None
        """The robot driver: ComputerLinkRobot, or EgmRobotDriver with ``[robot] kind = "egm"``."""
        self.sensor: Any = None
        """The sensor driver: Jr3CanSensor, or NetFtSensor with ``[sensor] kind = "netft"``."""
        self.egm: Opened[Any, Any] | None = None
        """The EGM driver and (emulated cell) its controller emulator."""
        self.netft: Opened[Any, Any] | None = None
        """The Net F/T driver and (emulated cell) its box emulator."""
        self.cell: Cell | None = None
        self.calibration: Calibration | None = None
        self._egm_route = egm_route
        self._stack = contextlib.ExitStack()
        try:
            self._open(seed)
        except BaseException:
            self.close()
            raise

    def _open(self, seed: int) -> None:
        cfg = self.config
        if cfg.calibration_file is not None:
            self.calibration = load_calibration(cfg.calibration_file)
        if cfg.robot_emulated or cfg.sensor_emulated:
            self.sponge, self.physics = emulated_physics(cfg)
        # Order (and so the close order): the far ends first, then the drivers.
        robot_url = self._start_link_emulator() if cfg.robot_kind == "computer_link" else None
        if cfg.sensor_kind == "jr3":
            self._open_jr3_bus(seed)
        if cfg.robot_kind == "egm":
            self.egm = open_egm(cfg, self.physics, self._egm_route)
            self._stack.callback(self.egm.close)  # the driver, then its emulator
            self.robot = self.egm.driver
        else:
            self._open_link(robot_url)
        if cfg.sensor_kind == "netft":
            self.netft = open_netft(cfg, self.physics, seed)
            self._stack.callback(self.netft.close)  # the driver, then its emulator
            self.sensor = self.netft.driver
        else:
            self._open_jr3()
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
        )
        if self.calibration is not None:
            self._apply_calibration(self.calibration, self.robot, self.cell)

    def _start_link_emulator(self) -> str | None:
        """Start the in-process robot-controller emulator if the link is emulated; its URL."""
        cfg = self.config
        if not cfg.robot_emulated:
            return None
        assert self.physics is not None  # built for any emulated device
        self.robot_emulator = emulated_robot(cfg, self.physics, "inproc")
        self._stack.callback(self.robot_emulator.close)
        return self.robot_emulator.start()

    def _open_link(self, emulator_url: str | None) -> None:
        """The computer-link driver, on the emulator's pty or the configured serial port."""
        robot_config = self.config.link
        if emulator_url is not None:
            robot_config = replace(robot_config, url=emulator_url)
        try:
            self.robot = ComputerLinkRobot(robot_config)
        except LinkError as exc:  # keeps its type (LinkTimeout, ProtocolError...)
            exc.add_note(
                "check [robot] url (port name), baudrate and framing, that the "
                "controller is on and its computer link enabled"
            )
            raise
        self._stack.callback(self.robot.close)

    def _open_jr3_bus(self, seed: int) -> None:
        """The JR3's CAN bus: the in-process emulator's (``forcelearn-jr3``), or the adapter."""
        cfg = self.config
        if cfg.sensor_emulated:
            assert self.physics is not None  # built for any emulated device
            channel = private_channel(cfg)
            self.sensor_emulator = emulated_jr3(cfg, self.physics, channel, seed, in_process=True)
            self._stack.callback(self.sensor_emulator.close)
            self._bus = can.Bus(interface="forcelearn-jr3", channel=channel)
        else:
            try:
                self._bus = can.Bus(
                    interface=cfg.bus.interface, channel=cfg.bus.channel, bitrate=cfg.bus.bitrate,
                    **cfg.bus.can_kwargs(),
                )
            except (can.CanError, OSError, ValueError, ImportError) as exc:
                raise SensorBusError(
                    f"cannot open CAN interface {cfg.bus.interface!r} channel "
                    f"{cfg.bus.channel!r} at {cfg.bus.bitrate} bit/s: {exc}; check the "
                    "adapter is plugged in, the interface name and the channel "
                    "(e.g. socketcan/can0, pcan/PCAN_USBBUS1, slcan/<serial port>)"
                ) from exc
        self._stack.callback(self._bus.shutdown)
        if cfg.bus.interface == "slcan" and not cfg.sensor_emulated:  # a real slcanBus
            self._slcan_barrier()

    def _slcan_barrier(self) -> None:
        """Wait until the slcan adapter has taken its open commands (a ``V`` round trip).

        python-can writes the adapter's close/bitrate/open lines and returns at
        once; the adapter reads them later. Asking its version and waiting for
        the answer puts the channel's opening before any robot traffic of this
        session, always: an emulated cell that starts afresh on that opening
        (``forcelearn emulate --fresh-per-connection``) then sees one order on
        any host. An adapter that does not answer only costs the wait.
        """
        bus = self._bus
        assert isinstance(bus, slcanBus)  # the caller checked [sensor] interface = "slcan"
        try:
            hardware, software = bus.get_version(SLCAN_VERSION_TIMEOUT_S)
        except can.CanError as exc:  # the JR3's initialisation then names the fault
            log.warning("slcan adapter on %s: version query failed: %s",
                        self.config.bus.channel, exc)
            return
        if hardware is None:
            log.warning("slcan adapter on %s did not answer the version query within %.1f s",
                        self.config.bus.channel, SLCAN_VERSION_TIMEOUT_S)
        else:
            log.info("slcan adapter on %s: hardware %s, software %s",
                     self.config.bus.channel, hardware, software)

    def _open_jr3(self) -> None:
        """The JR3 driver on the open bus, initialised."""
        cfg = self.config
        assert self._bus is not None
        self.sensor = Jr3CanSensor(self._bus, cfg.jr3)
        self._stack.callback(self.sensor.close)
        try:
            self.sensor.initialise()
        except ForcelearnError as exc:  # keeps its type and attributes
            exc.add_note(
                f"check [sensor] node_id ({cfg.jr3.node_id}), the bus bitrate and "
                "that the JR3 adapter is powered"
            )
            raise

    def _apply_calibration(
        self, calibration: Calibration, robot: Any, cell: Cell
    ) -> None:
        """Give the filter R from the measured noise; install bias and gravity compensation."""
        cfg = self.config
        if cfg.sensor.zero_on_init:  # zeroed just now, at the pose the robot is in
            calibration = calibration.rezeroed(robot.read_pose().quaternion)
        measured_at = calibration.sensor.cutoff_hz
        cutoff_hz = getattr(cfg.sensor, "cutoff_hz", None)  # a Net F/T filters in the box
        if measured_at and cutoff_hz is not None and abs(measured_at - cutoff_hz) > 0.01:
            log.warning(
                "the calibration measured the noise at a %.2f Hz cut-off, the sensor "
                "runs at %.2f Hz: R may be wrong; calibrate again",
                measured_at,
                cutoff_hz,
            )
        self.calibration = calibration
        cell.force_filter.set_measurement_variance(calibration.noise_variance(cfg.filter.axis))
        cell.compensation = calibration.compensation

        def rezero(pose: Pose) -> None:  # a tare zeroed the tool's weight at this pose
            self.calibration = calibration.rezeroed(pose.quaternion)
            cell.compensation = self.calibration.compensation

        cell.on_tare = rezero
        log.info(
            "calibration %s applied: R = %.4g, tool %.3f kg",
            cfg.calibration_file,
            calibration.noise_variance(cfg.filter.axis),
            calibration.tool.mass_kg,
        )

    @property
    def emulated(self) -> bool:
        """True when any device is emulated."""
        return self.physics is not None

    def emulator_state(self) -> dict[str, Any]:
        """What the emulators must restore for a bit-identical resume (JSON-able)."""
        state: dict[str, Any] = {}
        if self.physics is not None:
            state["clock"] = self.physics.clock.state_dict()
            if self.physics.motion is not None:
                state["motion"] = self.physics.motion.state_dict()
        if self.robot_emulator is not None:
            state["link"] = self.robot_emulator.engine.state_dict()
        if self.sponge is not None:
            state["sponge"] = self.sponge.state_dict()
        if self.sensor_emulator is not None:
            state["jr3"] = _jsonable(self.sensor_emulator.state_dict())
        if self.egm is not None and self.egm.emulator is not None:
            state["egm"] = {
                "controller": self.egm.emulator.state_dict(),
                "driver": self.egm.driver.state_dict(),
            }
        if self.netft is not None and self.netft.emulator is not None:
            state["netft"] = _jsonable(self.netft.emulator.state_dict())
        return state

    def load_emulator_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`emulator_state` (after the drivers' initialisation)."""
        if self.physics is not None:
            if "clock" in state:
                self.physics.clock.load_state_dict(state["clock"])
            if self.physics.motion is not None and "motion" in state:
                self.physics.motion.load_state_dict(state["motion"])
                self.physics.set_pose(self.physics.motion.pose)
        if self.robot_emulator is not None and "link" in state:
            self.robot_emulator.engine.load_state_dict(state["link"])
        if self.sponge is not None and "sponge" in state:
            self.sponge.load_state_dict(state["sponge"])
        if self.sensor_emulator is not None and "jr3" in state:
            self.sensor_emulator.load_state_dict(state["jr3"])
        if self.egm is not None and self.egm.emulator is not None and "egm" in state:
            self.egm.emulator.load_state_dict(state["egm"]["controller"])
            self.egm.driver.load_state_dict(state["egm"]["driver"])
        if self.netft is not None and self.netft.emulator is not None and "netft" in state:
            # What the driver sent while initialising (set bias needs no answer) takes
            # effect before the checkpoint's state, never after it.
            sent = self.netft.driver.stats.requests
            if not self.netft.emulator.wait_handled(sent, NETFT_SETTLE_TIMEOUT_S):
                log.warning("the Net F/T emulator did not handle the driver's %d request(s) "
                            "within %.1f s; the resumed run may differ", sent,
                            NETFT_SETTLE_TIMEOUT_S)
            self.netft.emulator.load_state_dict(state["netft"])

    def close(self) -> None:
        """Stop the robot, release the devices, stop the emulators; safe to call twice."""
        self._stack.close()

    def __enter__(self) -> CellSession:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _jsonable(value: Any) -> Any:
    """Turn numpy arrays and scalars inside nested dicts/lists into plain Python values."""
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value
