"""The example configs: the emulated one is the built-in default key for key; the real one loads."""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link.config import LinkConfig
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.errors import ConfigError
from forcelearn.filtering import ForceFilterConfig
from forcelearn.learning import SRVParams
from forcelearn.site.config import BusConfig, SafetyLimits, load_cell_config
from forcelearn.tasks.surface import SurfaceTaskSpec
from forcelearn.tasks.surface_probe import ProbeSpec

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
EMULATED = EXAMPLES / "emulated-cell.toml"
REAL = EXAMPLES / "real-cell.toml"

NOT_IN_TOML = {"limits", "stale_timeout_s", "full_scales", "log_path", "sleep_after_open_s",
               "direction"}
"""Fields a file cannot or must not set: limits come from [safety], None defaults stay unset."""
DERIVED = {"tolerance_n", "output_centre_y_mm", "output_scale_mm", "max_offset_mm"}
"""[task] keys whose default is derived (from the desired force, or the probe): shown commented."""
TABLES: dict[str, tuple[type, ...]] = {
    "robot": (LinkConfig,),
    "sensor": (BusConfig, Jr3Config),
    "filter": (ForceFilterConfig,),
    "safety": (SafetyLimits,),
    "task": (SurfaceTaskSpec,),
    "learner": (SRVParams,),
    "probe": (ProbeSpec,),
    "emulator.sponge": (SpongeParams,),
    "emulator.sensor": (Jr3ModelParams,),
    "emulator.arm": (ArmConfig,),
    "emulator.arm.home": (Pose,),
}


def test_the_emulated_example_is_exactly_the_built_in_default() -> None:
    """Loading examples/emulated-cell.toml gives the same CellConfig as no file at all."""
    assert replace(load_cell_config(EMULATED), source=None) == load_cell_config()


@pytest.mark.parametrize("table", sorted(TABLES))
def test_the_emulated_example_shows_every_parameter(table: str) -> None:
    """Each field of each table is written out (a new field must be added to the example)."""
    data = tomllib.loads(EMULATED.read_text())
    for part in table.split("."):
        data = data[part]
    fields = {f.name for cls in TABLES[table] for f in dataclasses.fields(cls) if f.init}
    missing = sorted(fields - NOT_IN_TOML - DERIVED - set(data))
    assert not missing, f"examples/emulated-cell.toml lacks [{table}] {missing}: add them"


def test_the_derived_task_keys_are_shown_commented() -> None:
    """The keys the probe (or the desired force) sets are in the example, commented out."""
    text = EMULATED.read_text()
    for key in sorted(DERIVED):
        assert f"# {key} = " in text, key


def test_a_changed_emulated_example_is_no_longer_the_default(tmp_path: Path) -> None:
    """The equality above is not vacuous: one changed physical value breaks it."""
    changed = tmp_path / "cell.toml"
    changed.write_text(EMULATED.read_text().replace("y_mm = 0.0", "y_mm = 1.0"))
    config = load_cell_config(changed)
    assert config.emulator.arm.home.y_mm == 1.0
    assert replace(config, source=None) != load_cell_config()


def test_the_real_cell_example_loads_as_a_real_cell() -> None:
    """Serial port, slcan on a USB adapter at 1 Mbit/s, normal force axis, limits, calibration."""
    config = load_cell_config(REAL)
    assert not config.robot_emulated and not config.sensor_emulated
    assert (config.robot.url, config.robot.baudrate) == ("/dev/ttyS0", 9600)
    assert (config.bus.interface, config.bus.channel, config.bus.bitrate) == (
        "slcan", "/dev/ttyACM0", 1_000_000
    )
    assert config.sensor.node_id == 1 and (config.filter.axis, config.filter.sign) == (1, -1.0)
    assert config.safety.max_force_n == 60.0 and config.robot.limits.max_step_mm == 10.0
    assert config.calibration_file == EXAMPLES / "calibration.toml"


@pytest.mark.parametrize(
    "text", ["[emulator.arm]\nhome = 3\n", "[emulator.arm.home]\nx_mm = 900.0\nw = 1\n"]
)
def test_a_bad_home_pose_is_an_error_naming_the_key(tmp_path: Path, text: str) -> None:
    """[emulator.arm.home] must be a table of Pose fields; anything else names the key."""
    path = tmp_path / "cell.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=r"emulator\.arm\.home"):
        load_cell_config(path)


@pytest.mark.parametrize(
    ("text", "named"),
    [
        ("[emulator.sensor]\nemulate_filter = 1\n", r"emulator\.sensor\.emulate_filter = 1: "
                                                     "must be true or false"),
        ("[safety]\nworkspace_min_mm = [700.0, -60.0]\n",
         r"safety\.workspace_min_mm = \(700\.0, -60\.0\): must be a list of 3"),
        ("[task]\ntolerance_n = \"5\"\n", r"task\.tolerance_n = '5': must be a number or unset"),
        ("[robot]\nbaudrate = 9600.5\n", r"robot\.baudrate = 9600\.5: must be a whole number"),
        ("[emulator.arm]\njoint_limits_deg = [[0, 1], [0, 1, 2]]\n",
         r"emulator\.arm\.joint_limits_deg"),
        ("[calibration]\nfile = 3\n", r"calibration\.file = 3"),
        ("[emulator.arm]\nforearm_mm = 0.0\n", "forearm_mm must be a finite length > 0"),
        ("[sensor]\ncutoff_hz = inf\n", r"cutoff_hz=inf is outside"),
        ("[sensor]\nack_timeout_s = 1e12\n",
         r"sensor\.ack_timeout_s = 1000000000000\.0: a time of at most"),
        ("[emulator.sensor]\nnoise_std = [inf, 0.2, 0.2, 0.02, 0.02, 0.02]\n",
         "noise_std must be finite"),
        ("[safety]\nworkspace_max_mm = [1100.0, 60.0, inf]\n", "must be 3 finite numbers"),
        ("[task]\nsamples_per_step = 1000000\n", r"task\.samples_per_step = 1000000: at most"),
        ("[sensor]\nbitrate = -1000000\n", r"sensor\.bitrate = -1000000: a CAN bit rate"),
        ("[sensor]\ninterface = \"\"\n", r"sensor\.interface and sensor\.channel"),
    ],
)
def test_a_value_of_the_wrong_type_length_or_size_names_the_key(
    tmp_path: Path, text: str, named: str
) -> None:
    """Each setting is checked against its annotation (type, list length) before it is used."""
    path = tmp_path / "cell.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=named):
        load_cell_config(path)


def test_samples_per_step_come_from_the_window_up_to_a_ceiling() -> None:
    """The window's samples at the sensor's period, and a window that holds too many refused."""
    from forcelearn.tasks.surface import MAX_SAMPLES_PER_STEP, SurfaceTaskSpec

    assert SurfaceTaskSpec(measurement_window_s=0.025).samples_for(0.000325) == 77
    assert SurfaceTaskSpec(samples_per_step=12).samples_for(0.000325) == 12
    too_long = MAX_SAMPLES_PER_STEP * 0.000325 * 1.01
    with pytest.raises(ConfigError, match="shorten the window"):
        SurfaceTaskSpec(measurement_window_s=too_long).samples_for(0.000325)
