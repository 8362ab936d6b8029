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
``[task]``     the §5 surface task (:class:`SurfaceTaskSpec`)
``[learner]``  SRV hyperparameters (§5 values as defaults)
``[probe]``    the surface probe before learning (:class:`ProbeSpec`)
``[run]``      ``trials``, ``seed``, ``stop_after_converged``, ``learner_start``
               ("probe", the default, or "cold": :mod:`forcelearn.tasks.surface_warm_start`)
``[emulator]`` ``time_scale`` (0: as fast as possible; 1: real time), ``profile``
               ("realistic", or "ideal": no time on wires, instant arm, no
               relaxation, no adapter filter); physics of the emulated cell:
               ``[emulator.sponge]``, ``[emulator.sensor]`` (the JR3's
               :class:`SensorModelParams`, or with ``[sensor] kind = "netft"``
               the Net F/T's :class:`NetFtModelParams`), ``[emulator.arm]``,
               ``[emulator.egm]`` (EGM control lag: :class:`ServoParams`)
               (ignored on a real cell)
``[calibration]`` ``file``: a calibration TOML from ``forcelearn calibrate``
=============  ===============================================================

One rule selects an emulated device: the key that says where the device is
(``url`` of the computer link, ``interface`` of the JR3's CAN bus, ``host``
of EGM and of the Net F/T) set to ``"emulated"``; a table that does not set
that key is emulated too, so an empty config is the emulated cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal, TypedDict

from forcelearn.config import build, check_sections, read_run_table, read_toml
from forcelearn.devices import Pose
from forcelearn.drivers.computer_link.config import Limits, LinkConfig
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.netft.config import NetFtConfig
from forcelearn.emulators.egm.servo import ServoParams
from forcelearn.emulators.jr3.sensor_model import SensorModelParams
from forcelearn.emulators.netft.sensor_model import NetFtModelParams
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.emulators.robot_controller.kinematics import ArmConfig
from forcelearn.errors import ConfigError
from forcelearn.filtering import ForceFilterConfig
from forcelearn.learning import SRVParams
from forcelearn.tasks.surface import SurfaceTaskSpec, check_task_limits
from forcelearn.tasks.surface_probe import ProbeSpec
from forcelearn.tasks.surface_warm_start import check_learner_start

EMULATED = "emulated"
ROBOT_KINDS = ("computer_link", "egm")
"""``[robot] kind``: the ABB computer link (serial) or Externally Guided Motion (UDP)."""
SENSOR_KINDS = ("jr3", "netft")
"""``[sensor] kind``: the JR3 behind its CAN adapter, or an ATI Net F/T box (Ethernet)."""
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

NETFT_RDT_HZ = 7000.0
"""The Net F/T's RDT rate when the config names none (the emulator's default), Hz."""
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


class CanBusKwargs(TypedDict, total=False):
    """Extra keyword arguments of ``can.Bus`` that a ``[sensor]`` table may set."""

    sleep_after_open: float
    """python-can's slcan wait after opening the adapter, s."""


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
    sensor: SensorModelParams = field(default_factory=SensorModelParams)
    arm: ArmConfig = field(default_factory=ArmConfig)
    netft: NetFtModelParams = field(default_factory=NetFtModelParams)
    """The emulated Net F/T's model (``[emulator.sensor]`` when ``[sensor] kind = "netft"``)."""
    egm: ServoParams = field(default_factory=ServoParams)
    """EGM control lag (dead time) and servo time constant of the emulated controller."""
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
        """The models with the profile applied (the ideal profile switches time off)."""
        if not self.ideal:
            return self
        return replace(
            self,
            sponge=replace(self.sponge, relaxation_ratio=0.0),
            sensor=replace(self.sensor, emulate_filter=False),
            arm=replace(self.arm, instant=True, reply_latency_s=0.0),
        )


@dataclass(frozen=True)
class CellConfig:
    """Everything ``forcelearn run`` and ``forcelearn check`` need."""

    robot: LinkConfig | EgmConfig = field(
        default_factory=lambda: LinkConfig(
            url=EMULATED,
            ack_timeout_s=EMULATED_LINK_TIMEOUT_S,
            reply_timeout_s=EMULATED_LINK_TIMEOUT_S,
        )
    )
    bus: BusConfig = field(default_factory=BusConfig)
    sensor: Jr3Config | NetFtConfig = field(default_factory=lambda: Jr3Config(zero_on_init=True))
    filter: ForceFilterConfig = field(
        default_factory=lambda: ForceFilterConfig(axis=1, sign=-1.0, noise_cutoff_hz=125.0)
    )
    safety: SafetyLimits = field(default_factory=SafetyLimits)
    task: SurfaceTaskSpec = field(default_factory=SurfaceTaskSpec)
    learner: SRVParams = field(default_factory=lambda: SRVParams(**SECTION_LEARNER_DEFAULTS))
    emulator: EmulatorConfig = field(default_factory=EmulatorConfig)
    probe: ProbeSpec = field(default_factory=ProbeSpec)
    calibration_file: Path | None = None
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
        """``"computer_link"`` or ``"egm"``."""
        return "egm" if isinstance(self.robot, EgmConfig) else "computer_link"

    @property
    def sensor_kind(self) -> str:
        """``"jr3"`` or ``"netft"``."""
        return "netft" if isinstance(self.sensor, NetFtConfig) else "jr3"

    @property
    def link(self) -> LinkConfig:
        """``robot`` of a computer-link cell (``ConfigError`` for another kind)."""
        if not isinstance(self.robot, LinkConfig):
            raise ConfigError(f"the robot is of kind {self.robot_kind!r}, not computer_link")
        return self.robot

    @property
    def egm(self) -> EgmConfig:
        """``robot`` of an EGM cell (``ConfigError`` for another kind)."""
        if not isinstance(self.robot, EgmConfig):
            raise ConfigError(f"the robot is of kind {self.robot_kind!r}, not egm")
        return self.robot

    @property
    def jr3(self) -> Jr3Config:
        """``sensor`` of a JR3 cell (``ConfigError`` for another kind)."""
        if not isinstance(self.sensor, Jr3Config):
            raise ConfigError(f"the sensor is of kind {self.sensor_kind!r}, not jr3")
        return self.sensor

    @property
    def netft(self) -> NetFtConfig:
        """``sensor`` of a Net F/T cell (``ConfigError`` for another kind)."""
        if not isinstance(self.sensor, NetFtConfig):
            raise ConfigError(f"the sensor is of kind {self.sensor_kind!r}, not netft")
        return self.sensor

    @property
    def robot_emulated(self) -> bool:
        """True when the robot goes to the built-in emulator."""
        if isinstance(self.robot, EgmConfig):
            return self.robot.host == EMULATED
        return self.robot.url == EMULATED

    @property
    def sensor_emulated(self) -> bool:
        """True when the sensor goes to the built-in emulator."""
        if isinstance(self.sensor, NetFtConfig):
            return self.sensor.host == EMULATED
        return self.bus.interface == EMULATED


_BUS_KEYS = {"interface", "channel", "bitrate", "sleep_after_open_s"}


def _with_home_pose(arm: dict[str, Any] | None) -> dict[str, Any] | None:
    """``[emulator.arm.home]`` (x_mm, y_mm, z_mm, quaternion) as a Pose."""
    if not arm or "home" not in arm:
        return arm
    if not isinstance(arm["home"], dict):
        raise ConfigError("emulator.arm.home: a table with x_mm, y_mm, z_mm, quaternion")
    return {**arm, "home": build(Pose, arm["home"], "emulator.arm.home")}


def _kind(table: dict[str, Any], section: str, kinds: tuple[str, ...]) -> str:
    """Pop ``kind`` from a device table (default: the first of ``kinds``); name a bad one."""
    kind = table.pop("kind", kinds[0])
    if kind not in kinds:
        raise ConfigError(f"{section}.kind = {kind!r}: one of {list(kinds)}")
    known: str = kind  # one of ``kinds``
    return known


def _load_robot(table: dict[str, Any], limits: Limits) -> LinkConfig | EgmConfig:
    """``[robot]`` by its kind; the limits always come from ``[safety]``."""
    kind = _kind(table, "robot", ROBOT_KINDS)
    if "limits" in table:
        raise ConfigError("robot.limits: set the limits in [safety] (one place for all limits)")
    if kind == "computer_link":
        table = {"url": EMULATED, **table}
        if table["url"] == EMULATED:
            for key in ("ack_timeout_s", "reply_timeout_s"):
                table.setdefault(key, EMULATED_LINK_TIMEOUT_S)
        return replace(build(LinkConfig, table, "robot"), limits=limits)
    table.setdefault("host", EMULATED)
    if "max_speed_mm_s" in table:  # EGM's ramp-speed ceiling is a robot key, not a [safety] one
        current = {f.name: getattr(limits, f.name) for f in fields(limits)}
        limits = build(Limits, {**current, "max_speed_mm_s": table.pop("max_speed_mm_s")},
                       "robot")
    return build(EgmConfig, {**table, "limits": limits}, "robot")


def load_cell_config(path: str | Path | None = None) -> CellConfig:
    """Read a cell config (or return the emulated default); errors name the key."""
    data = read_toml(path) if path else {}
    check_sections(
        data,
        {
            "robot",
            "sensor",
            "filter",
            "safety",
            "task",
            "learner",
            "run",
            "emulator",
            "calibration",
            "probe",
        },
    )
    safety = build(SafetyLimits, data.get("safety"), "safety")
    limits = Limits(safety.workspace_min_mm, safety.workspace_max_mm, safety.max_step_mm)
    robot = _load_robot(dict(data.get("robot", {})), limits)

    sensor_table = dict(data.get("sensor", {}))
    sensor_kind = _kind(sensor_table, "sensor", SENSOR_KINDS)
    bus = BusConfig()
    if sensor_kind == "jr3":
        bus = build(
            BusConfig,
            {k: sensor_table.pop(k) for k in list(sensor_table) if k in _BUS_KEYS},
            "sensor",
        )
        emulated_sensor = bus.interface == EMULATED
    else:
        sensor_table.setdefault("host", EMULATED)
        emulated_sensor = sensor_table["host"] == EMULATED
    if emulated_sensor and "stale_sensor_s" not in data.get("safety", {}):
        safety = replace(safety, stale_sensor_s=EMULATED_STALE_SENSOR_S)
    if "stale_timeout_s" in sensor_table:
        raise ConfigError("sensor.stale_timeout_s: set safety.stale_sensor_s instead")
    sensor_table.setdefault("zero_on_init", True)
    sensor_cls: type[Jr3Config] | type[NetFtConfig] = (
        Jr3Config if sensor_kind == "jr3" else NetFtConfig
    )
    sensor = build(
        sensor_cls, {**sensor_table, "stale_timeout_s": safety.stale_sensor_s}, "sensor"
    )

    filter_table = {
        "axis": 1,
        "sign": -1.0,
        # the adapter's low-pass colours the noise (the Net F/T emulator's is white)
        "noise_cutoff_hz": getattr(sensor, "cutoff_hz", 0.0),
        **({"sample_period_s": 1.0 / (getattr(sensor, "rdt_rate_hz", None) or NETFT_RDT_HZ)}
           if sensor_kind == "netft" else {}),
        **data.get("filter", {}),
    }
    emulator_table = dict(data.get("emulator", {}))
    check_sections(emulator_table, {"sponge", "sensor", "arm", "egm", "time_scale", "profile"})
    pace = {k: emulator_table.pop(k) for k in ("time_scale", "profile") if k in emulator_table}
    sensor_model = emulator_table.get("sensor")
    emulator = build(
        EmulatorConfig,
        {
            **pace,
            "sponge": build(SpongeParams, emulator_table.get("sponge"), "emulator.sponge"),
            "sensor": build(
                SensorModelParams,
                sensor_model if sensor_kind == "jr3" else None,
                "emulator.sensor",
            ),
            "netft": build(
                NetFtModelParams,
                sensor_model if sensor_kind == "netft" else None,
                "emulator.sensor",
            ),
            "arm": build(ArmConfig, _with_home_pose(emulator_table.get("arm")), "emulator.arm"),
            "egm": build(ServoParams, emulator_table.get("egm"), "emulator.egm"),
        },
        "emulator",
    )
    run_table = dict(data.get("run", {}))
    learner_start = check_learner_start(run_table.pop("learner_start", DEFAULT_LEARNER_START))
    stop_after = run_table.pop("stop_after_converged", 0)
    if isinstance(stop_after, bool) or not isinstance(stop_after, int) or stop_after < 0:
        raise ConfigError(f"run.stop_after_converged = {stop_after!r}: a whole number >= 0")
    trials, seed = read_run_table({"run": run_table}, DEFAULT_TRIALS)
    calibration = dict(data.get("calibration", {}))
    if set(calibration) - {"file"}:
        raise ConfigError("[calibration] takes one key, file")
    calibration_file = None
    if "file" in calibration:
        if not isinstance(calibration["file"], str) or not calibration["file"]:
            raise ConfigError(f"calibration.file = {calibration['file']!r}: the path of a "
                              "calibration file written by forcelearn calibrate")
        calibration_file = Path(calibration["file"])
        if not calibration_file.is_absolute() and path is not None:
            calibration_file = Path(path).parent / calibration_file
    task = build(SurfaceTaskSpec, data.get("task"), "task")
    check_task_limits(task, safety.max_force_n, safety.workspace_min_mm, safety.workspace_max_mm)
    return CellConfig(
        robot=robot,
        bus=bus,
        sensor=sensor,
        filter=build(ForceFilterConfig, filter_table, "filter"),
        safety=safety,
        task=task,
        learner=build(
            SRVParams, {**SECTION_LEARNER_DEFAULTS, **data.get("learner", {})}, "learner"
        ),
        emulator=emulator,
        probe=build(ProbeSpec, data.get("probe"), "probe"),
        calibration_file=calibration_file,
        trials=trials,
        seed=seed,
        stop_after_converged=stop_after,
        learner_start=learner_start,
        source=Path(path) if path else None,
    )
