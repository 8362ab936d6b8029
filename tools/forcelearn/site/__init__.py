"""Open a cell as its config says: the library's front door.

What ``can.Bus`` is to python-can and ``gymnasium.make`` to Gymnasium. A cell
config (a TOML file; no file: the emulated cell) names a robot and a force
sensor of the kinds in :mod:`forcelearn.site.kinds`; :class:`CellSession`
opens both, on the real devices or on the built-in emulators, and hands the
trainer a :class:`~forcelearn.cell.Cell`::

    from forcelearn.site import CellSession, load_cell_config

    config = load_cell_config("examples/egm-cell.toml")   # or None: the emulated cell
    with CellSession(config, seed=0) as session:
        cell = session.cell
        cell.move_in_steps(config.task.start_pose(), config.safety.max_step_mm)
        print(f"{cell.measure_force_n():.2f} N")   # the filtered normal force

:class:`EmulatedCell` serves the emulated devices of any two kinds to
another process (what ``forcelearn emulate`` runs); :func:`robot_kind` and
:func:`sensor_kind` look a kind up in the table, :func:`register` adds one.
Gymnasium environments over a session are in :mod:`forcelearn.envs`.
"""

from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.site.emulated_cell import EmulatedCell
from forcelearn.site.kinds import (
    ROBOT_KINDS,
    SENSOR_KINDS,
    RobotKind,
    SensorKind,
    register,
    robot_kind,
    sensor_kind,
)
from forcelearn.site.session import CellSession

__all__ = [
    "ROBOT_KINDS",
    "SENSOR_KINDS",
    "CellConfig",
    "CellSession",
    "EmulatedCell",
    "RobotKind",
    "SensorKind",
    "load_cell_config",
    "register",
    "robot_kind",
    "sensor_kind",
]
