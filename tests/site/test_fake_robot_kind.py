"""A robot kind added through the kinds table alone loads, opens, steps, checks, serves, is refused.

The fake "slide" robot below is a whole kind in one module: its config type,
its ``[emulator.slide]`` model table, its route options, an in-process
emulator moving the cell's physics, a driver, and the
:class:`~forcelearn.site.kinds.RobotKind` that ties them together. Nothing else
of forcelearn is told about it: its entry in the table (or an installed entry
point of the ``forcelearn.kinds`` group) is enough for the config loader, the
session, ``check``, the emulated cell, and the twin, which refuses it cleanly
because the kind gives no polling model.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint
from pathlib import Path

import numpy as np
import pytest

from forcelearn.config import build
from forcelearn.devices import Pose, Robot
from forcelearn.drivers.limits import Limits
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError, SafetyStop
from forcelearn.site import CellSession, EmulatedCell, kinds, load_cell_config
from forcelearn.site.kinds import (
    CellView,
    FarEnd,
    FarEndOptions,
    Printer,
    RobotConfig,
    RobotKind,
    UnmodelledKind,
)
from forcelearn.tasks.surface import SurfaceTask
from forcelearn.tools import cli
from forcelearn.tools.twin.arm import polling_of


@dataclass(frozen=True)
class _SlideConfig:
    """The slide's ``[robot]`` table: where it is; the limits come from [safety]."""

    where: str = "emulated"
    limits: Limits = field(default_factory=Limits)


@dataclass(frozen=True)
class _SlideModel:
    """``[emulator.slide]``: how long the emulated slide takes per move, s."""

    move_s: float = 0.004


@dataclass(frozen=True)
class _SlideRoute:
    """The slide's own route options (what EGM's EgmRoute is to EGM)."""

    lane: str = "main"


class _SlideEmulator:
    """The far end: every move lands at once, ``move_s`` of simulated time later."""

    def __init__(self, physics: CellPhysics, model: _SlideModel, lane: str) -> None:
        self.physics, self.model, self.lane = physics, model, lane
        self.moves = 0
        self.closed = False

    def start(self) -> str:
        return self.lane

    def close(self) -> None:
        self.closed = True

    def move(self, pose: Pose) -> float:
        self.physics.clock.advance(self.model.move_s)
        self.physics.set_pose(pose)
        self.moves += 1
        return self.physics.clock.now_s


class _SlideRobot:
    """The driver: a Robot over the emulator that refuses targets outside its limits."""

    def __init__(self, emulator: _SlideEmulator, limits: Limits) -> None:
        self.emulator, self.limits = emulator, limits
        self.target = emulator.physics.pose
        self.arrived_s = emulator.physics.clock.now_s
        self.closed = False

    def read_pose(self) -> Pose:
        return self.emulator.physics.pose

    def read_target(self) -> Pose:
        return self.target

    def move_to(self, pose: Pose) -> None:
        low, high = np.array(self.limits.workspace_min_mm), np.array(self.limits.workspace_max_mm)
        if np.any(pose.position_mm < low) or np.any(pose.position_mm > high):
            raise SafetyStop(f"slide target {pose} outside the workspace")
        self.target = pose
        self.arrived_s = self.emulator.move(pose)

    def wait_in_position(self, timeout_s: float, settle_s: float = 0.0) -> float:
        return self.arrived_s + settle_s

    def stop(self) -> None:
        """Nothing moves between calls."""

    def close(self) -> None:
        self.closed = True


class _SlideFarEnd(FarEnd):
    def __init__(self, physics: CellPhysics, model: _SlideModel, lane: str) -> None:
        super().__init__()
        self.emulator: _SlideEmulator = _SlideEmulator(physics, model, lane)
        self.emulators = [self.emulator]

    def state_dict(self) -> dict[str, object]:
        return {"moves": self.emulator.moves}

    def describe(self, paths: dict[str, str]) -> str:
        return f"slide: in process, lane {self.emulator.lane}"

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        return ['kind = "slide"', 'where = "emulated"']

    def summary(self) -> str:
        return f"{self.emulator.moves} slide moves"


class _SlideKind(RobotKind):
    name = "slide"
    label = "slide"
    config_type = _SlideConfig
    emulated_key = "where"
    emulator_table = "slide"
    model_type = _SlideModel

    def load(self, table: dict[str, object], limits: Limits) -> _SlideConfig:
        return build(_SlideConfig, {**table, "limits": limits}, "robot")

    def emulated(self, robot: RobotConfig) -> bool:
        return isinstance(robot, _SlideConfig) and robot.where == "emulated"

    def describe(self, config: CellView) -> str:
        return "built-in slide emulator" if config.robot_emulated else "a real slide"

    def location(self, config: CellView) -> str:
        return "slide"

    def far_end(self, config: CellView, physics: CellPhysics,
                options: FarEndOptions) -> _SlideFarEnd:
        model = self.model(config.emulator)
        route = options.routes.get(self.name, _SlideRoute())
        assert isinstance(model, _SlideModel) and isinstance(route, _SlideRoute)
        return _SlideFarEnd(physics, model, route.lane)

    def open(self, config: CellView, far_end: FarEnd | None,
             stack: contextlib.ExitStack) -> _SlideRobot:
        if not isinstance(far_end, _SlideFarEnd):
            raise ConfigError("no real slide exists")
        robot = _SlideRobot(far_end.emulator, config.robot.limits)
        stack.callback(robot.close)
        far_end.driver = robot
        return robot

    def check(self, robot: Robot, say: Printer) -> Callable[[], None]:
        assert isinstance(robot, _SlideRobot)
        before = robot.emulator.moves
        say(f"  robot   slide at y {robot.read_pose().y_mm:.2f} mm, {before} moves")

        def unmoved() -> None:
            if robot.emulator.moves != before:
                raise SafetyStop("the slide moved during the check")

        return unmoved

    def calibration_name(self, robot: Robot) -> str:
        return "slide"


KIND = _SlideKind()
"""What an entry point of the ``forcelearn.kinds`` group would name."""


@pytest.fixture
def slide(monkeypatch: pytest.MonkeyPatch) -> Iterator[_SlideKind]:
    """The slide's entry in the robot table, for this test only."""
    monkeypatch.setitem(kinds.ROBOT_KINDS, "slide", KIND)
    yield KIND


def _config(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "slide-cell.toml"
    path.write_text(f'[robot]\nkind = "slide"\n[emulator.slide]\nmove_s = 0.01\n{extra}')
    return path


def test_an_unregistered_robot_kind_is_a_config_error_naming_the_known_ones(
    tmp_path: Path,
) -> None:
    """Without the table entry the file is refused, and the message lists the robot kinds."""
    with pytest.raises(ConfigError, match=r"robot\.kind = 'slide': one of \['computer_link', "):
        load_cell_config(_config(tmp_path))


def test_the_kind_loads_its_tables_opens_and_runs_task_steps(
    slide: _SlideKind, tmp_path: Path
) -> None:
    """Its [robot] and [emulator.slide] tables load; the session opens it and the task steps."""
    config = load_cell_config(_config(tmp_path))
    assert (config.robot_kind, config.sensor_kind) == ("slide", "jr3")
    assert config.robot_emulated and isinstance(config.robot, _SlideConfig)
    assert config.robot.limits.max_step_mm == config.safety.max_step_mm  # [safety]'s limits
    assert config.emulator.devices["slide"] == _SlideModel(move_s=0.01)
    with CellSession(config, seed=2, routes={"slide": _SlideRoute("side")}) as session:
        assert isinstance(session.robot, _SlideRobot) and session.cell is not None
        assert session.robot_emulator.lane == "side"  # its route options reached it
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
        task.reset()
        forces = [task.step(np.array([-8.0])).force_n for _ in range(2)]
        assert all(np.isfinite(forces)) and max(forces) > 1.0  # pressed into the sponge
        state = session.emulator_state()
        assert state["slide"] == {"moves": session.robot_emulator.moves} and "egm" not in state
        robot = session.robot
    assert robot.closed


def test_a_table_another_robot_kind_owns_is_refused(slide: _SlideKind, tmp_path: Path) -> None:
    """[emulator.egm] belongs to the EGM kind: a slide cell refuses it, naming its own tables."""
    with pytest.raises(ConfigError, match=r"emulator\.egm: no device of this cell takes it"):
        load_cell_config(_config(tmp_path, "[emulator.egm]\ncontrol_lag_s = 0.1\n"))


def test_check_passes_on_the_kind(slide: _SlideKind, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    """``forcelearn check`` opens the slide, lets its kind report, and passes."""
    assert cli.main(["check", "--config", str(_config(tmp_path)), "--seconds", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "built-in slide emulator" in out and "slide at y" in out
    assert out.rstrip().endswith("the robot was not moved")


def test_the_emulated_cell_serves_the_kind(slide: _SlideKind) -> None:
    """``forcelearn emulate``'s class serves it beside a sensor of another kind."""
    with EmulatedCell(load_cell_config(), robot="slide", sensor="netft") as cell:
        assert cell.describe()[0] == "slide: in process, lane main"
        assert '[robot]\nkind = "slide"\nwhere = "emulated"\n' in cell.site_config()
        assert cell.summary().startswith("0 slide moves")


def test_the_twin_refuses_a_kind_without_a_polling_model(slide: _SlideKind,
                                                         tmp_path: Path) -> None:
    """The twin asks the kind how its driver polls; this one gives none: a typed error."""
    config = load_cell_config(_config(tmp_path))
    with pytest.raises(UnmodelledKind, match="robot kind 'slide' gives no polling model"):
        polling_of(config.robot)
    assert issubclass(UnmodelledKind, ConfigError)  # the CLI prints it as one line, exit 1


def test_an_installed_entry_point_adds_the_kind(monkeypatch: pytest.MonkeyPatch) -> None:
    """A distribution's ``forcelearn.kinds`` entry point is found by name, as python-can's are."""
    monkeypatch.setattr(kinds, "ROBOT_KINDS", dict(kinds.ROBOT_KINDS))
    point = EntryPoint("slide", f"{__name__}:KIND", kinds.ENTRY_POINT_GROUP)
    monkeypatch.setattr(kinds, "installed_entry_points", lambda: [point])
    assert kinds.robot_kind("slide") is KIND
    assert "slide" in kinds.known("robot")
    assert kinds.robot_kind_of(_SlideConfig()) is KIND
