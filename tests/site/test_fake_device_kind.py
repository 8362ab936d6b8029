"""A device kind added through the kinds table alone opens a cell, runs steps, checks and serves.

The fake "gauge" sensor below is a whole kind in a few lines: its config type,
an in-process emulator reading the cell's physics, a driver, and the
:class:`~forcelearn.site.kinds.SensorKind` that ties them together. Nothing
else of forcelearn is told about it: registering it in the table is enough for
the config loader, the session, the emulated cell, ``check`` and the live page.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from forcelearn.calibration import SensorInfo
from forcelearn.config import build
from forcelearn.devices import WrenchSample
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError
from forcelearn.site import CellSession, EmulatedCell, kinds, load_cell_config, register
from forcelearn.site.kinds import FarEnd, FarEndOptions, SensorKind
from forcelearn.tasks.surface import SurfaceTask
from forcelearn.tools.commands.check import check_session
from forcelearn.tools.live.publish import surface_meta

SAMPLE_PERIOD_S = 0.001


@dataclass(frozen=True)
class _GaugeConfig:
    """The fake gauge's table: where it is, and the two keys every sensor takes."""

    where: str = "emulated"
    stale_timeout_s: float = 0.1
    zero_on_init: bool = True


class _GaugeEmulator:
    """The far end: reads the cell's true wrench, one sample per simulated millisecond."""

    def __init__(self, physics: CellPhysics) -> None:
        self.physics = physics
        self.samples = 0
        self.closed = False

    @property
    def address(self) -> str:
        return "in-process gauge"

    def start(self) -> str:
        return self.address

    def close(self) -> None:
        self.closed = True

    def sample(self) -> np.ndarray:
        self.physics.clock.advance(SAMPLE_PERIOD_S)
        self.samples += 1
        return np.asarray(self.physics.true_wrench(), dtype=float)


class _GaugeDriver:
    """The driver: a ForceSensor over the emulator (offsets taken on zeroing)."""

    sample_period_s = SAMPLE_PERIOD_S

    def __init__(self, emulator: _GaugeEmulator) -> None:
        self.emulator = emulator
        self.offsets = np.zeros(6)
        self.closed = False

    def read(self) -> WrenchSample:
        wrench = self.emulator.sample() - self.offsets
        return WrenchSample(wrench, 0.0, self.emulator.samples, sensor_dt_s=SAMPLE_PERIOD_S)

    def zero_offsets(self) -> None:
        self.offsets = self.offsets + self.read().wrench

    def close(self) -> None:
        self.closed = True


class _GaugeFarEnd(FarEnd):
    def __init__(self, physics: CellPhysics) -> None:
        super().__init__()
        self.emulator = _GaugeEmulator(physics)
        self.emulators = [self.emulator]

    def state_dict(self) -> dict[str, Any]:
        return {"samples": self.emulator.samples}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.emulator.samples = state["samples"]

    def describe(self, paths: dict[str, str]) -> str:
        return "gauge: in process"

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        return ['kind = "gauge"', 'where = "emulated"']

    def summary(self) -> str:
        return f"{self.emulator.samples} gauge samples"


class _GaugeKind(SensorKind):
    name = "gauge"
    label = "gauge"
    config_type = _GaugeConfig

    def load(self, table: dict[str, Any]) -> _GaugeConfig:
        return build(_GaugeConfig, table, "sensor")

    def emulated(self, sensor: _GaugeConfig, bus: Any) -> bool:
        return sensor.where == "emulated"

    def describe(self, config: Any) -> str:
        return f"gauge at {config.sensor.where}"

    def location(self, config: Any) -> str:
        return f"gauge at {config.sensor.where}"

    def far_end(self, config: Any, physics: CellPhysics, options: FarEndOptions) -> _GaugeFarEnd:
        return _GaugeFarEnd(physics)

    def open(self, config: Any, far_end: FarEnd | None,
             stack: contextlib.ExitStack) -> _GaugeDriver:
        if far_end is None:
            raise ConfigError("no real gauge exists")
        driver = _GaugeDriver(far_end.emulator)
        stack.callback(driver.close)
        far_end.driver = driver
        if config.sensor.zero_on_init:
            driver.zero_offsets()
        return driver

    def check(self, sensor: _GaugeDriver, config: Any, seconds: float,
              say: Callable[[str], None]) -> None:
        say(f"  sensor  gauge reads {sensor.read().wrench[1]:+.3f} N on Fy")

    def calibration_info(self, config: Any, sensor: _GaugeDriver, robot_name: str,
                         model: str | None, serial: str) -> SensorInfo:
        return SensorInfo(model=model or "gauge", serial=serial, robot=robot_name)


@pytest.fixture
def gauge(monkeypatch: pytest.MonkeyPatch) -> Iterator[_GaugeKind]:
    """The gauge's entry in the sensor table, for this test only."""
    kind = _GaugeKind()
    monkeypatch.setitem(kinds.SENSOR_KINDS, "gauge", kind)
    yield kind


def _config(tmp_path: Path) -> Path:
    path = tmp_path / "gauge-cell.toml"
    path.write_text('[sensor]\nkind = "gauge"\n')
    return path


def test_an_unregistered_kind_is_a_config_error_naming_the_known_ones(tmp_path: Path) -> None:
    """Without the table entry the same file is refused, and the message lists the kinds."""
    with pytest.raises(ConfigError, match=r"sensor\.kind = 'gauge': one of \['jr3', 'netft'\]"):
        load_cell_config(_config(tmp_path))


def test_a_kind_registered_in_the_table_opens_a_cell_and_runs_steps(
    gauge: _GaugeKind, tmp_path: Path
) -> None:
    """Load, open, move and measure through the gauge; its state is saved under its name."""
    config = load_cell_config(_config(tmp_path))
    assert (config.robot_kind, config.sensor_kind) == ("computer_link", "gauge")
    assert config.sensor_emulated and config.sensor.stale_timeout_s == 10.0  # the emulated rule
    with CellSession(config, seed=1) as session:
        assert isinstance(session.sensor, _GaugeDriver)
        assert session.physics is not None and session.sensor_emulator.physics is session.physics
        assert session.cell is not None
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
        task.reset()
        forces = [task.step(np.array([-8.0])).force_n for _ in range(2)]
        assert all(np.isfinite(forces)) and max(forces) > 1.0  # pressed into the sponge
        state = session.emulator_state()
        assert state["gauge"] == {"samples": session.sensor_emulator.samples} and "jr3" not in state
        lines: list[str] = []
        check_session(session, 0.1, lines.append)
        assert any("gauge reads" in line for line in lines)
        gauge_driver = session.sensor
    assert gauge_driver.closed and session.sensor_emulator.closed
    assert surface_meta(config, 1).devices[1] == "sensor: emulated gauge"


def test_the_emulated_cell_serves_the_registered_kind(gauge: _GaugeKind) -> None:
    """``forcelearn emulate``'s class serves it beside a real kind and writes its table."""
    with EmulatedCell(load_cell_config(), robot="computer_link", sensor="gauge") as cell:
        assert cell.describe()[1] == "gauge: in process"
        assert '[sensor]\nkind = "gauge"\nwhere = "emulated"\n' in cell.site_config()
        assert cell.summary().endswith("0 gauge samples")


def test_register_adds_a_kind_under_its_name(monkeypatch: pytest.MonkeyPatch) -> None:
    """``register`` is the table entry: the lookup finds the object, the loader its config."""
    monkeypatch.setattr(kinds, "SENSOR_KINDS", dict(kinds.SENSOR_KINDS))
    kind = _GaugeKind()
    register(kind)
    assert kinds.sensor_kind("gauge") is kind
    assert kinds.kind_of("sensor", _GaugeConfig()) is kind
