"""The cell configuration: one TOML file describes a real or an emulated cell and its run.

Tables (every key optional; defaults are the emulated cell and the paper's §5):

=============  ===============================================================
table          holds
=============  ===============================================================
``[robot]``    ``kind = "computer_link"`` (default): ``url``, ``baudrate``,
               ``bytesize``, ``parity``, ``stopbits``, ``ack_timeout_s``,
               ``reply_timeout_s``, ``nak_retries``, ``enq_retries``
               (``url = "emulated"`` starts the robot-controller emulator on a pty);
               ``kind = "egm"``: the keys of :class:`EgmConfig` (``host``,
               ``port``, ``version``, ``speed_mm_s``...; ``host = "emulated"``
               starts the EGM controller emulator on loopback UDP, in lockstep)
``[sensor]``   ``kind = "jr3"`` (default): CAN bus ``interface``, ``channel``,
               ``bitrate``; JR3 adapter ``node_id``, ``mode``, ``cutoff_hz``,
               ``period_us``, ``full_scales``, ``ack_timeout_s``,
               ``opcodes_version``, ``log_path`` (``interface = "emulated"``
               starts the JR3 emulator on the in-process virtual bus);
               ``kind = "netft"``: the keys of :class:`NetFtConfig` (``host``,
               ``rdt_port``, ``calibration_source``...; ``host = "emulated"``
               starts the Net F/T emulator on loopback)
``[filter]``   the Kalman force filter; ``axis`` and ``sign`` pick the normal force
``[safety]``   ``max_force_n``, ``max_step_mm``, ``workspace_min_mm``,
               ``workspace_max_mm``, ``stale_sensor_s``: always on, never off
``[task]``     the §5 surface task (:class:`SurfaceTaskSpec`); ``kind = "path"``: docs/path.md
``[learner]``  SRV hyperparameters (§5 values as defaults)
``[probe]``    the surface probe before learning (:class:`ProbeSpec`)
``[run]``      ``trials``, ``seed``, ``stop_after_converged``, ``learner_start``
               ("probe", the default, or "cold": :mod:`forcelearn.tasks.surface_warm_start`)
``[emulator]`` ``time_scale`` (0: as fast as possible; 1: real time), ``profile``
               ("realistic", or "ideal": no time on wires, instant arm, no
               relaxation, no adapter filter); physics of the emulated cell:
               ``[emulator.sponge]``, ``[emulator.arm]``, ``[emulator.tool]`` (the
               tool: :mod:`forcelearn.site.emulated_tool`), ``[emulator.part]``; each device
               kind's model table (:attr:`~forcelearn.site.kinds.DeviceKind.emulator_table`):
               ``[emulator.sensor]`` the sensor's (the JR3's ``Jr3ModelParams``,
               the Net F/T's ``NetFtModelParams``), ``[emulator.egm]`` EGM's
               control lag (``ServoParams``) (ignored on a real cell)
``[calibration]`` ``file``: a calibration TOML from ``forcelearn calibrate``; ``sensor_serial``:
               this sensor's serial (a file of another is refused);
               ``mounting_rpy_deg`` or ``mounting_quaternion``: the sensor's
               mounting on the flange as drawn, taken as given by ``forcelearn
               calibrate`` (default: estimated with the tool)
=============  ===============================================================

The kinds are the entries of :mod:`forcelearn.site.kinds`; each builds its
device table. One rule selects an emulated device: the key that says where the device is
(``url`` of the computer link, ``interface`` of the JR3's CAN bus, ``host``
of EGM and of the Net F/T) set to ``"emulated"``; a table that does not set
that key is emulated too, so an empty config is the emulated cell.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from forcelearn.config import build, check_sections, read_run_table, read_toml
from forcelearn.devices import Pose
from forcelearn.drivers.limits import Limits
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.errors import ConfigError
from forcelearn.filtering import ForceFilterConfig
from forcelearn.learning import SRVParams
from forcelearn.site import part_config as parts
from forcelearn.site.calibration_identity import load_sensor_serial
from forcelearn.site.emulated_tool import load_mounting, load_tool
from forcelearn.site.kinds import (
    DEFAULT_ROBOT_KIND,
    DEFAULT_SENSOR_KIND,
    CanBusKwargs,
    DeviceKind,
    RobotConfig,
    RobotKind,
    SensorConfig,
    SensorKind,
    robot_kind,
    robot_kind_of,
    sensor_kind,
    sensor_kind_of,
)
from forcelearn.tasks.surface import SurfaceTaskSpec, check_task_limits
from forcelearn.tasks.surface_probe import ProbeSpec
from forcelearn.tasks.surface_warm_start import check_learner_start

EMULATED = "emulated"
DEFAULT_TRIALS = 300
"""Trials of a run when neither the config nor the command line says."""
DEFAULT_LEARNER_START = "probe"
"""``[run] learner_start`` of a new run: the probe's warm start (docs/surface.md says why)."""
EMULATED_STALE_SENSOR_S = 10.0
"""Stale-sensor watchdog of the in-process emulated sensor when the file sets none, s.

On a real sensor silence is a fault and 0.1 s is the default. In emulation the
sensor is a thread of this process, so its only "silence" is a stall of the
host (a loaded CI machine): a longer watchdog keeps such stalls from stopping
runs or from re-sending SYNCs, which would change the emulated noise sequence
(a run at load average 15-25 on two cores diverged with 1 s: the driver
presumes samples lost after half the watchdog and asks again). Results are
identical as long as no stall of the host lasts longer than half of it."""

EMULATED_LINK_TIMEOUT_S = 10.0
"""ACK and reply timeouts of the robot link to the in-process emulator when the file sets none, s.

As for the sensor's watchdog: the emulator is a thread of this process, so a
late answer can only be a stall of the host (seen at a load average of 15 on
two cores); on a real link 1 s stays the default. A timeout that fires sends an
ENQ, whose bytes the simulated clock does see, so the timeouts are long."""

SECTION_LEARNER_DEFAULTS: dict[str, Any] = {
    "gamma": 0.8,  # γ, §5
    "alpha_generalized": 0.5,  # α, §5 generalized
    "beta_generalized": 0.5,  # β, §5 generalized
    "alpha_specialized": 1.0,  # α, §5 specialized
    "beta_specialized": 0.5,  # β, §5 specialized
    "extent": (3,),  # d, one input (not given in §5)
    "success_trials": 10,  # N, §5
}
"""The paper's §5 values for the learner (the §4 ones are SRVParams' own defaults)."""


@dataclass(frozen=True)
class SafetyLimits:
    """Limits on every path that moves the robot; they cannot be switched off.

    Units in the names. The computer-link driver enforces the step and the
    workspace before any byte is sent; the sensor driver raises ``SensorStale``
    after ``stale_sensor_s`` without a sample; the cell retracts and fails the
    trial above ``max_force_n``.
    """

    max_force_n: float = 60.0
    """Largest force before the cell retracts (3 x the §5 target): the filtered normal
    force, and the magnitude of every sample's (Fx, Fy, Fz)."""
    max_step_mm: float = 10.0
    workspace_min_mm: tuple[float, float, float] = (700.0, -60.0, -130.0)
    workspace_max_mm: tuple[float, float, float] = (1100.0, 60.0, 700.0)
    stale_sensor_s: float = 0.1
    """Watchdog on a real sensor, s (the emulated cell uses EMULATED_STALE_SENSOR_S)."""
    move_timeout_s: float = 10.0
    """Longest wait for a move to be reported in position (robot's clock), s."""

    def __post_init__(self) -> None:
        for name in ("max_force_n", "max_step_mm", "stale_sensor_s", "move_timeout_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(
                    f"safety.{name} = {value!r}: must be a finite number > 0; safety limits "
                    "cannot be switched off"
                )
        for name in ("workspace_min_mm", "workspace_max_mm"):
            corner = getattr(self, name)
            if len(corner) != 3 or not all(math.isfinite(v) for v in corner):
                raise ConfigError(f"safety.{name} = {corner!r}: must be 3 finite numbers "
                                  "(x, y, z), mm; the workspace cannot be switched off")
        Limits(self.workspace_min_mm, self.workspace_max_mm, self.max_step_mm)


@dataclass(frozen=True)
class BusConfig:
    """Which python-can bus reaches the JR3 adapter."""

    interface: str = EMULATED
    channel: str = "forcelearn-jr3"
    bitrate: int = 1_000_000
    sleep_after_open_s: float | None = None
    """slcan only: python-can's wait after opening the adapter, s (None: its default, 2 s)."""

    def __post_init__(self) -> None:
        if not self.interface or not self.channel:
            raise ConfigError("sensor.interface and sensor.channel must name a python-can bus "
                              "(e.g. \"slcan\" and \"/dev/ttyACM0\")")
        if not 0 < self.bitrate <= 8_000_000:
            raise ConfigError(f"sensor.bitrate = {self.bitrate}: a CAN bit rate in bit/s, "
                              "1..8000000 (the JR3 adapter: 1000000)")
        wait = self.sleep_after_open_s
        if wait is not None and (self.interface != "slcan" or not 0 <= wait <= 10):
            raise ConfigError(
                f"sensor.sleep_after_open_s={wait}: only for interface \"slcan\", 0..10 s"
            )

    def can_kwargs(self) -> CanBusKwargs:
        """Extra keyword arguments for ``can.Bus`` (python-can's ``sleep_after_open``)."""
        if self.sleep_after_open_s is None:
            return {}
        return {"sleep_after_open": self.sleep_after_open_s}


PROFILES = ("realistic", "ideal")


@dataclass(frozen=True)
class EmulatorConfig:
    """Pace, time profile, physics and device models of the emulated cell."""

    sponge: SpongeParams = field(default_factory=SpongeParams)
    arm: ArmConfig = field(default_factory=ArmConfig)
    devices: Mapping[str, object] = field(default_factory=dict)
    """Kind name -> the model its ``[emulator.*]`` table built (the JR3's
    :class:`~forcelearn.emulators.jr3.sensor_model.Jr3ModelParams`, EGM's
    :class:`~forcelearn.emulators.egm.servo.ServoParams`...); a kind absent takes its
    defaults (:meth:`~forcelearn.site.kinds.DeviceKind.model`)."""
    tool: ToolParams = field(default_factory=ToolParams)
    """The tool on the sensor (``[emulator.tool]``, :mod:`forcelearn.site.emulated_tool`)."""
    part: parts.PartSetup | None = None  # [emulator.part] (site/part_config.py); None: sponge
    time_scale: float = 0.0
    """0: as fast as possible (simulated time only); 1.0: real time; any factor between."""
    profile: Literal["realistic", "ideal"] = "realistic"
    """"ideal": wires cost no time, the arm is instant, no relaxation, no adapter filter."""

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ConfigError(f"emulator.profile = {self.profile!r}: one of {list(PROFILES)}")
        scale = self.time_scale
        if not (isinstance(scale, int | float) and math.isfinite(scale) and scale >= 0):
            raise ConfigError(
                f"emulator.time_scale = {scale!r}: a number >= 0 (0: as fast as possible, "
                "1: real time)"
            )

    @property
    def ideal(self) -> bool:
        """True for the zero-time profile."""
        return self.profile == "ideal"

    def effective(self) -> EmulatorConfig:
        """The physics with the profile applied (the ideal profile switches time off).

        A device's model takes the profile in its kind (the JR3's adapter filter).
        """
        if not self.ideal:
            return self
        return replace(
            self,
            sponge=replace(self.sponge, relaxation_ratio=0.0),
            arm=replace(self.arm, instant=True, reply_latency_s=0.0),
        )


def _default_robot() -> RobotConfig:
    """The emulated computer link (its defaults, with the emulator's link timeouts)."""
    return robot_kind(DEFAULT_ROBOT_KIND).load({}, Limits())


def _default_sensor() -> SensorConfig:
    """The emulated JR3, zeroed on opening."""
    return sensor_kind(DEFAULT_SENSOR_KIND).load({"zero_on_init": True})


@dataclass(frozen=True)
class CellConfig:
    """Everything ``forcelearn run`` and ``forcelearn check`` need."""

    robot: RobotConfig = field(default_factory=_default_robot)
    """The robot's config, of its kind's type (:data:`~forcelearn.site.kinds.ROBOT_KINDS`)."""
    bus: BusConfig = field(default_factory=BusConfig)
    sensor: SensorConfig = field(default_factory=_default_sensor)
    """The sensor's config, of its kind's type (:data:`~forcelearn.site.kinds.SENSOR_KINDS`)."""
    filter: ForceFilterConfig = field(
        default_factory=lambda: ForceFilterConfig(axis=1, sign=-1.0, noise_cutoff_hz=125.0)
    )
    safety: SafetyLimits = field(default_factory=SafetyLimits)
    task: SurfaceTaskSpec = field(default_factory=SurfaceTaskSpec)
    path_task: parts.PathTaskSpec | None = None  # [task] kind = "path"; None: the §5 task runs
    learner: SRVParams = field(default_factory=lambda: SRVParams(**SECTION_LEARNER_DEFAULTS))
    emulator: EmulatorConfig = field(default_factory=EmulatorConfig)
    probe: ProbeSpec = field(default_factory=ProbeSpec)
    calibration_file: Path | None = None
    sensor_serial: str = ""
    """``[calibration] sensor_serial``: the serial of this cell's sensor; a calibration file
    of another serial is refused (:mod:`forcelearn.site.calibration_identity`)."""
    calibration_mounting: tuple[float, float, float, float] | None = None
    """``[calibration] mounting_rpy_deg`` or ``mounting_quaternion`` (w, x, y, z): the sensor's
    mounting on the flange, given; None: ``forcelearn calibrate`` estimates it."""
    trials: int = DEFAULT_TRIALS
    seed: int = 0
    stop_after_converged: int = 0
    """``[run] stop_after_converged``: end a run this many trials after it converged (0: never;
    studies use it to spend no time on runs already decided)."""
    learner_start: str = DEFAULT_LEARNER_START
    """``[run] learner_start``: "probe" (the SRV units start on the probe's path, their
    spread from its uncertainty) or "cold" (μ = 0, the paper's §5); docs/surface.md."""
    source: Path | None = None

    def __post_init__(self) -> None:
        check_learner_start(self.learner_start)

    @property
    def robot_kind(self) -> str:
        """``[robot] kind``: its name in :data:`~forcelearn.site.kinds.ROBOT_KINDS`."""
        return self.robot_device.name

    @property
    def sensor_kind(self) -> str:
        """``[sensor] kind``: its name in :data:`~forcelearn.site.kinds.SENSOR_KINDS`."""
        return self.sensor_device.name

    @property
    def robot_device(self) -> RobotKind:
        """The robot's entry of the kinds table."""
        return robot_kind_of(self.robot)

    @property
    def sensor_device(self) -> SensorKind:
        """The sensor's entry of the kinds table."""
        return sensor_kind_of(self.sensor)

    @property
    def robot_emulated(self) -> bool:
        """True when the robot goes to the built-in emulator."""
        return self.robot_device.emulated(self.robot)

    @property
    def sensor_emulated(self) -> bool:
        """True when the sensor goes to the built-in emulator."""
        return self.sensor_device.emulated(self.sensor, self.bus)


SECTIONS = frozenset({
    "robot", "sensor", "filter", "safety", "task", "learner", "run", "emulator", "calibration",
    "probe",
})
"""The tables of a cell config."""


def load_cell_config(path: str | Path | None = None, task_path: Path | None = None) -> CellConfig:
    """Read a cell config (or return the emulated default); errors name the key.

    Each table has its builder below; the rules that carry a value from one
    table into another are the named functions after them.
    """
    data = read_toml(path) if path else {}
    check_sections(data, set(SECTIONS))
    safety = build(SafetyLimits, data.get("safety"), "safety")
    robot_table = dict(data.get("robot", {}))
    robot_device = robot_kind(robot_table.pop("kind", DEFAULT_ROBOT_KIND))
    robot = load_robot(robot_device, robot_table, robot_limits(safety))
    sensor_table = dict(data.get("sensor", {}))
    kind = sensor_kind(sensor_table.pop("kind", DEFAULT_SENSOR_KIND))  # ConfigError names them
    bus = load_bus(kind, sensor_table)
    sensor = load_sensor(kind, sensor_table, safety)
    safety = emulated_sensor_watchdog(safety, kind.emulated(sensor, bus), data.get("safety", {}))
    sensor = load_sensor(kind, sensor_table, safety)  # with the watchdog that applies
    path_task = parts.load_path_task(data.get("task"), path, task_path)  # --path: task_path
    task = SurfaceTaskSpec() if path_task else build(SurfaceTaskSpec, data.get("task"), "task")
    check_task_limits(task, safety.max_force_n, safety.workspace_min_mm, safety.workspace_max_mm)
    stop_after, learner_start, trials, seed = load_run(dict(data.get("run", {})))
    return CellConfig(
        robot=robot,
        bus=bus,
        sensor=sensor,
        filter=build(ForceFilterConfig, filter_table(kind, sensor, parts.filter_keys(
            path_task, data.get("filter", {}), None if path_task is None else parts.sensor_mounting(
                data.get("calibration", {}),
                load_calibration_file(data.get("calibration", {}), path)))), "filter"),
        safety=safety,
        task=task,
        path_task=path_task,
        learner=build(
            SRVParams, {**SECTION_LEARNER_DEFAULTS, **data.get("learner", {})}, "learner"
        ),
        emulator=load_emulator((robot_device, kind), dict(data.get("emulator", {})), path),
        probe=build(ProbeSpec, data.get("probe"), "probe"),
        calibration_file=load_calibration_file(data.get("calibration", {}), path),
        sensor_serial=load_sensor_serial(data.get("calibration", {})),
        calibration_mounting=load_mounting(data.get("calibration", {}), "calibration"),
        trials=trials,
        seed=seed,
        stop_after_converged=stop_after,
        learner_start=learner_start,
        source=Path(path) if path else None,
    )


# -- one builder per table ---------------------------------------------------------------


def load_robot(kind: RobotKind, table: dict[str, Any], limits: Limits) -> RobotConfig:
    """``[robot]`` (``kind`` removed): its kind's builder, with the limits of [safety]."""
    if "limits" in table:
        raise ConfigError("robot.limits: set the limits in [safety] (one place for all limits)")
    return kind.load(table, limits)


def load_bus(kind: SensorKind, table: dict[str, Any]) -> BusConfig:
    """The CAN bus keys of ``[sensor]`` (popped from ``table``); the default for a bus-less kind."""
    bus_table = kind.take_bus(table)
    return BusConfig() if bus_table is None else build(BusConfig, bus_table, "sensor")


def load_sensor(kind: SensorKind, table: dict[str, Any], safety: SafetyLimits) -> SensorConfig:
    """``[sensor]`` (bus keys removed): its kind's builder, with the watchdog of [safety]."""
    if "stale_timeout_s" in table:
        raise ConfigError("sensor.stale_timeout_s: set safety.stale_sensor_s instead")
    return kind.load({"zero_on_init": True, **table, "stale_timeout_s": safety.stale_sensor_s})


PHYSICS_TABLES = ("sponge", "arm", "tool", "part")
"""``[emulator.*]`` tables of the cell's physics, which every kind shares."""


def load_emulator(kinds: tuple[DeviceKind, ...], table: dict[str, Any],
                  config_path: str | Path | None = None) -> EmulatorConfig:
    """``[emulator]``: pace, profile, physics, and each device kind's model table.

    The cell's robot and sensor kinds own their tables (``[emulator.sensor]``
    the sensor's model, ``[emulator.egm]`` EGM's servo...:
    :attr:`~forcelearn.site.kinds.DeviceKind.emulator_table`); ``kinds[-1]`` is
    the sensor's, whose model bounds ``[emulator.tool]``.
    """
    owners = {kind.emulator_table: kind for kind in kinds if kind.emulator_table is not None}
    for name in table:
        if isinstance(table[name], dict) and name not in PHYSICS_TABLES and name not in owners:
            raise ConfigError(
                f"emulator.{name}: no device of this cell takes it (physics tables: "
                f"{list(PHYSICS_TABLES)}; this cell's devices: {sorted(owners) or 'none'})"
            )
    check_sections(table, {*PHYSICS_TABLES, *owners, "time_scale", "profile"})
    pace: dict[str, Any] = {k: table.pop(k) for k in ("time_scale", "profile") if k in table}
    devices: dict[str, object] = {}
    for name, kind in owners.items():
        if kind.model_type is not None:
            devices[kind.name] = build(kind.model_type, table.get(name), f"emulator.{name}")
        elif name in table:
            raise ConfigError(f"emulator.{name}: the {kind.label} emulator takes no model table")
    emulator = build(
        EmulatorConfig,
        {
            **pace,
            "sponge": build(SpongeParams, table.get("sponge"), "emulator.sponge"),
            "arm": build(ArmConfig, _with_home_pose(table.get("arm")), "emulator.arm"),
            "devices": devices,
        },
        "emulator",
    )
    # [emulator.tool], checked against the range of the sensor kind's model
    model: Any = kinds[-1].model(emulator)
    return replace(emulator, tool=load_tool(table.get("tool"), model),
                   part=parts.load_part(table.get("part"), emulator.sponge, config_path))


def load_run(table: dict[str, Any]) -> tuple[int, str, int, int]:
    """``[run]``: (stop_after_converged, learner_start, trials, seed)."""
    learner_start = check_learner_start(table.pop("learner_start", DEFAULT_LEARNER_START))
    stop_after = table.pop("stop_after_converged", 0)
    if isinstance(stop_after, bool) or not isinstance(stop_after, int) or stop_after < 0:
        raise ConfigError(f"run.stop_after_converged = {stop_after!r}: a whole number >= 0")
    trials, seed = read_run_table({"run": table}, DEFAULT_TRIALS)
    return stop_after, learner_start, trials, seed


def load_calibration_file(table: dict[str, Any], config_path: str | Path | None) -> Path | None:
    """``[calibration] file``, relative to the config file's folder."""
    if set(table) - {"file", "sensor_serial", "mounting_rpy_deg", "mounting_quaternion"}:
        raise ConfigError("[calibration] takes the keys file, sensor_serial, mounting_rpy_deg "
                          "and mounting_quaternion")
    if "file" not in table:
        return None
    if not isinstance(table["file"], str) or not table["file"]:
        raise ConfigError(f"calibration.file = {table['file']!r}: the path of a "
                          "calibration file written by forcelearn calibrate")
    calibration_file = Path(table["file"])
    if not calibration_file.is_absolute() and config_path is not None:
        calibration_file = Path(config_path).parent / calibration_file
    return calibration_file


def _with_home_pose(arm: dict[str, Any] | None) -> dict[str, Any] | None:
    """``[emulator.arm.home]`` (x_mm, y_mm, z_mm, quaternion) as a Pose."""
    if not arm or "home" not in arm:
        return arm
    if not isinstance(arm["home"], dict):
        raise ConfigError("emulator.arm.home: a table with x_mm, y_mm, z_mm, quaternion")
    return {**arm, "home": build(Pose, arm["home"], "emulator.arm.home")}


# -- the rules that carry values between tables -------------------------------------------


def robot_limits(safety: SafetyLimits) -> Limits:
    """The robot driver's limits are [safety]'s workspace and step: one place for all limits."""
    return Limits(safety.workspace_min_mm, safety.workspace_max_mm, safety.max_step_mm)


def emulated_sensor_watchdog(
    safety: SafetyLimits, sensor_emulated: bool, safety_table: dict[str, Any]
) -> SafetyLimits:
    """An emulated sensor's watchdog is EMULATED_STALE_SENSOR_S unless [safety] names one.

    The emulated sensor is a thread of this process: its only silence is a stall
    of the host (see :data:`EMULATED_STALE_SENSOR_S`).
    """
    if sensor_emulated and "stale_sensor_s" not in safety_table:
        return replace(safety, stale_sensor_s=EMULATED_STALE_SENSOR_S)
    return safety


def filter_table(kind: SensorKind, sensor: SensorConfig, table: dict[str, Any]) -> dict[str, Any]:
    """``[filter]`` over its defaults: the normal force is -Fy, and the sensor's own.

    The sensor kind adds what follows from the device (the JR3 adapter's
    low-pass colours the noise; a Net F/T's sample period is its RDT rate's).
    """
    return {"axis": 1, "sign": -1.0, **kind.filter_defaults(sensor), **table}
