"""`[robot] kind = "egm"` and `[sensor] kind = "netft"`: config, examples, runs, resume."""

from __future__ import annotations

import importlib
import json
import re
from pathlib import Path

import pytest

from forcelearn.drivers.computer_link.config import LinkConfig
from forcelearn.drivers.egm import EgmConfig
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.netft import NetFtConfig
from forcelearn.errors import ConfigError
from forcelearn.site.config import EMULATED_STALE_SENSOR_S, load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TIMING_KEYS = {"wall_s", "steps_per_s", "realtime_factor"}


def write(tmp_path: Path, text: str) -> Path:
    """Write a cell config into ``tmp_path``; return its path."""
    path = tmp_path / "cell.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("name", "robot", "sensor"),
    [
        ("egm-cell.toml", EgmConfig, Jr3Config),
        ("netft-cell.toml", LinkConfig, NetFtConfig),
        ("egm-netft-cell.toml", EgmConfig, NetFtConfig),
    ],
)
def test_examples_load_as_emulated_cells_of_their_kinds(
    name: str, robot: type, sensor: type
) -> None:
    """Each example loads with its kinds, emulated as shipped, limits from [safety]."""
    config = load_cell_config(EXAMPLES / name)
    assert isinstance(config.robot, robot) and isinstance(config.sensor, sensor)
    assert config.robot_emulated and config.sensor_emulated
    assert config.safety.stale_sensor_s == EMULATED_STALE_SENSOR_S
    assert config.sensor.stale_timeout_s == EMULATED_STALE_SENSOR_S
    # the limits are [safety]'s whatever the robot kind
    assert config.robot.limits.max_step_mm == config.safety.max_step_mm
    assert config.robot.limits.workspace_min_mm == config.safety.workspace_min_mm


def test_defaults_stay_computer_link_and_jr3() -> None:
    """No config: the computer link and the JR3, as before the kinds."""
    config = load_cell_config(None)
    assert config.robot_kind == "computer_link" and config.sensor_kind == "jr3"


def test_a_real_egm_and_netft_cell_keeps_its_addresses(tmp_path: Path) -> None:
    """Real addresses are kept; a real sensor keeps the 0.1 s watchdog."""
    config = load_cell_config(write(tmp_path, """
[robot]
kind = "egm"
host = "192.168.125.100"
version = "rw6"
max_speed_mm_s = 200.0
[sensor]
kind = "netft"
host = "192.168.1.1"
"""))
    assert not config.robot_emulated and not config.sensor_emulated
    assert config.robot.host == "192.168.125.100" and config.robot.version == "rw6"
    assert config.robot.limits.max_speed_mm_s == 200.0
    assert config.sensor.stale_timeout_s == 0.1  # a real box: [safety]'s default
    assert config.sensor.zero_on_init  # as for the JR3: zeroed at initialisation


@pytest.mark.parametrize(
    ("text", "named"),
    [
        ('[robot]\nkind = "kuka"\n', "robot.kind"),
        ('[sensor]\nkind = "ati"\n', "sensor.kind"),
        ('[robot]\nkind = "egm"\nport = 70000\n', "robot.port"),
        ('[robot]\nkind = "egm"\nurl = "/dev/ttyS0"\n', "robot.url"),
        ('[robot]\nkind = "egm"\nversion = "rw5"\n', "robot.version"),
        ('[robot]\nkind = "egm"\ncontroller_host = "robot.local"\n', "robot.controller_host"),
        ('[robot]\nkind = "egm"\ncontroller_host = 3232235777\n', "robot.controller_host"),
        ('[robot]\nkind = "egm"\ncontroller_host = "192.168.125.1"\ncontroller_port = 70000\n',
         "robot.controller_port"),
        ('[robot]\nkind = "egm"\ncontroller_port = 6510\n', "robot.controller_port"),
        ('[robot]\nkind = "egm"\n[robot.limits]\nmax_step_mm = 1.0\n', "robot.limits"),
        ('[sensor]\nkind = "netft"\nhost = ""\n', "sensor.host"),
        ('[sensor]\nkind = "netft"\nnode_id = 1\n', "sensor.node_id"),
        ('[sensor]\nkind = "netft"\nrdt_port = -1\n', "sensor.rdt_port"),
        ('[sensor]\nkind = "netft"\nstale_timeout_s = 1.0\n', "sensor.stale_timeout_s"),
        ('[sensor]\nkind = "jr3"\nhost = "1.2.3.4"\n', "sensor.host"),
        ('[sensor]\nkind = "netft"\n[emulator.sensor]\nemulate_filter = false\n',
         "emulator.sensor.emulate_filter"),
        ('[robot]\nkind = "egm"\n[emulator.egm]\ncontrol_lag_s = -1.0\n', "emulator.egm"),
        ("[emulator.egm]\ncontrol_lag_s = 0.1\n", "emulator.egm: no device of this cell takes it"),
    ],
)
def test_errors_name_the_key(tmp_path: Path, text: str, named: str) -> None:
    """Every bad value or unknown key is named with its table."""
    with pytest.raises(ConfigError, match=named.replace(".", r"\.")):
        load_cell_config(write(tmp_path, text))


@pytest.mark.parametrize(
    ("module", "accessor", "own_cell"),
    [("computer_link_kind", "link_of", "default"), ("jr3_kind", "jr3_of", "default"),
     ("egm_kind", "egm_of", "egm-netft"), ("netft_kind", "netft_of", "egm-netft")],
)
def test_a_kind_asked_about_another_kinds_device_says_which(
    module: str, accessor: str, own_cell: str
) -> None:
    """Each kind's accessor reads its own cell and refuses another's with a ConfigError."""
    cells = {"default": load_cell_config(None),
             "egm-netft": load_cell_config(EXAMPLES / "egm-netft-cell.toml")}
    kind_module = importlib.import_module(f"forcelearn.site.{module}")
    read = getattr(kind_module, accessor)
    assert isinstance(read(cells[own_cell]), kind_module.KIND.config_type)
    other = cells["egm-netft" if own_cell == "default" else "default"]
    with pytest.raises(ConfigError, match=f"not the {re.escape(kind_module.KIND.label)}'s"):
        read(other)


def test_an_rdt_rate_the_emulated_box_cannot_stream_is_a_config_error(tmp_path: Path) -> None:
    """A real box may report any rate; the emulated one refuses, naming the key, before a run."""
    config = load_cell_config(write(tmp_path, '[sensor]\nkind = "netft"\nrdt_rate_hz = 14000\n'))
    with pytest.raises(ConfigError, match=r"sensor\.rdt_rate_hz = 14000"):
        CellSession(config, seed=0)


def test_emulated_egm_and_netft_share_one_arm_clock_and_physics() -> None:
    """EGM moves the shared arm the Net F/T emulator samples, on one clock."""
    config = load_cell_config(EXAMPLES / "egm-netft-cell.toml")
    with CellSession(config, seed=3) as session:
        egm, netft = session.robot_emulator, session.sensor_emulator
        assert egm is not None and netft is not None
        assert egm.physics is session.physics and netft.physics is session.physics
        assert egm.clock is session.physics.clock is netft.clock
        assert egm.model.motion.motion is session.physics.motion  # PhysicsMotion over the arm
        cell = session.cell
        assert cell is not None
        start = cell.sync()
        target = start.moved(0.0, 0.0, -5.0)
        cell.move_to(target)
        reached = session.physics.pose
        assert abs(reached.z_mm - target.z_mm) <= config.robot.in_position_mm
        assert session.physics.motion.target == target  # the arm took EGM's planned pose
        cell.measure_force_n()
        state = session.emulator_state()
    assert {"clock", "motion", "sponge", "egm", "netft"} <= set(state)
    assert state["clock"]["now_s"] > 0.1  # the move and the settle took simulated time


def run(config: Path, out: Path, *extra: str) -> dict:
    """``forcelearn run`` in this process; return its summary."""
    code = main(["run", "--config", str(config), "--out", str(out), "--no-progress", *extra])
    assert code in (0, None)
    return json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize(
    "name", [pytest.param("egm-cell.toml", marks=pytest.mark.long), "netft-cell.toml"]
)
def test_run_is_deterministic_and_resumes_bit_identical(name: str, tmp_path: Path) -> None:
    """1 trial, then resume to 3: the same bytes as 3 trials straight (seed 2).

    The first trial of the interrupted run is a second run of the same seed,
    so this is the determinism check too.
    """
    config = EXAMPLES / name
    whole = run(config, tmp_path / "a", "--trials", "3", "--seed", "2")
    csv = (tmp_path / "a" / "trials.csv").read_text()
    assert len(csv.splitlines()) == 4
    assert whole["cell_time_s"] > 0
    first = run(config, tmp_path / "c", "--trials", "1", "--seed", "2")
    assert (tmp_path / "c" / "trials.csv").read_text() == "".join(csv.splitlines(True)[:2])
    assert 0 < first["cell_time_s"] < whole["cell_time_s"]
    code = main(["run", "--resume", str(tmp_path / "c"), "--trials", "3", "--no-progress"])
    assert code in (0, None)
    assert (tmp_path / "c" / "trials.csv").read_text() == csv
    resumed = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert {k: v for k, v in resumed.items() if k not in TIMING_KEYS} == {
        k: v for k, v in whole.items() if k not in TIMING_KEYS
    }


def test_a_netft_zero_is_taken_before_the_host_goes_on(monkeypatch) -> None:
    """Set bias needs no answer; the emulated box takes it before ``zero_offsets`` returns.

    The emulator's thread is made slow on that request: a zero the host did
    not wait for would be taken after the robot turned (a host-load race).
    """
    import time

    config = load_cell_config(EXAMPLES / "netft-cell.toml")
    with CellSession(config, seed=0) as session:
        netft, sensor = session.sensor_emulator, session.sensor
        assert netft is not None and sensor is not None
        taken = netft.stats.bias_commands  # the zero of initialise, already taken
        assert taken >= 1
        handle = netft._handle_locked

        def slow(data: bytes, address: tuple[str, int]) -> None:
            time.sleep(0.2)
            handle(data, address)

        monkeypatch.setattr(netft, "_handle_locked", slow)
        sensor.zero_offsets()
        assert netft.stats.bias_commands == taken + 1
