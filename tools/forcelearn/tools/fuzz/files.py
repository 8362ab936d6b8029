"""The file fuzz targets: learner state, calibration and cell config files, mutated.

A :class:`FileCase` holds a file's good bytes, what loading them gives and how
to compare; :func:`check_file` loads a mutant and asks for the same value or
the case's typed error (``state``, ``calibration``, ``config`` targets; the
header and value mutants check only that no foreign exception escapes).
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from forcelearn.errors import ForcelearnError
from forcelearn.tools.fuzz.configs import odd_value
from forcelearn.tools.fuzz.harness import (
    FuzzFailure,
    Mutation,
    apply_mutations,
    foreign,
    random_mutations,
)
from forcelearn.tools.fuzz.loaders import calibration_value_mutant, npz_header_mutant

if TYPE_CHECKING:
    from forcelearn.calibration import Calibration
    from forcelearn.learning import SRVLearner

@dataclass
class FileCase:
    """A file's good bytes, what loading them gives, and a scratch path to write mutants to."""

    good: bytes
    expected: object
    path: Path
    load: Callable[[Path], object]
    same: Callable[[object, object], bool]
    error: type[ForcelearnError]
    compare: bool = True
    extra: dict[str, object] = field(default_factory=dict)


def check_file(case: FileCase, data: bytes) -> str:
    """Write ``data`` to the scratch path and load it: the expected value or the typed error."""
    case.path.write_bytes(data)
    try:
        value = case.load(case.path)
    except case.error:
        return "rejected"
    except Exception as exc:
        raise foreign(exc, f"loading a damaged {case.path.name}") from exc
    if case.compare and not case.same(value, case.expected):
        raise FuzzFailure(f"a damaged {case.path.name} loaded a different value")
    return "accepted"


def _same_learner(a: object, b: object) -> bool:
    # Both are what load_learner returns (the state case's loader): (learner, metadata).
    la, ma = cast("tuple[SRVLearner, dict[str, Any]]", a)
    lb, mb = cast("tuple[SRVLearner, dict[str, Any]]", b)
    return bool(
        np.array_equal(la.weights, lb.weights) and np.array_equal(la.predictions, lb.predictions)
        and la.schedule == lb.schedule and la.params == lb.params and ma == mb
        and la.grid.shape == lb.grid.shape
        and la.rng.bit_generator.state == lb.rng.bit_generator.state
    )


def state_case(folder: Path) -> FileCase:
    """A small trained learner saved to ``folder``."""
    from forcelearn.errors import StateFileError
    from forcelearn.learning import (
        BoxGrid,
        Dimension,
        SRVLearner,
        SRVParams,
        load_learner,
        save_learner,
    )

    grid = BoxGrid([Dimension("a", 0.0, 1.0, 4), Dimension("b", -1.0, 1.0, 3)])
    learner = SRVLearner(grid, 2, SRVParams(success_trials=3), rng=5)
    xs = np.random.default_rng(1).uniform([0, -1], [1, 1], size=(30, 2))
    for x in xs:
        step = learner.act(x)
        learner.learn(step, 0.5)
    learner.end_trial(True)
    path = folder / "learner.npz"
    save_learner(learner, path, metadata={"run": "fuzz", "trial": 1})
    good = path.read_bytes()
    return FileCase(good, load_learner(path), folder / "mutant.npz", load_learner, _same_learner,
                    StateFileError)


def state_header_case(folder: Path) -> FileCase:
    """The learner state with a member's ``.npy`` header damaged and the zip CRCs redone.

    Only property 1 holds: with the CRC recomputed the damage is an edit (``<f8`` to
    ``>f8`` is one bit and loads byte-swapped weights), which no check short of a digest
    could see; zip's CRC catches the same damage on disk.
    """
    case = state_case(folder)

    def header_mutant(rng: random.Random, good: bytes) -> bytes:
        return npz_header_mutant(rng, good,
                                 lambda data: apply_mutations(data, random_mutations(rng)))

    return FileCase(case.good, None, folder / "mutant-header.npz", case.load, case.same,
                    case.error, compare=False, extra={"mutant": header_mutant})


def filled_calibration() -> Calibration:
    """A plausible calibration with every section filled: a 1.5 kg tool on a 200/400 N sensor.

    Moment full scales 20 N*m; the sensor's model name holds an emoji, to exercise the
    file's text encoding.
    """
    from forcelearn.calibration import (
        Calibration,
        MatrixCheck,
        SensorInfo,
        estimate_noise,
        fit_tool_load,
    )
    from forcelearn.devices import STANDARD_GRAVITY_M_S2, TOOL_DOWN, quaternion_to_matrix

    rng = np.random.default_rng(0)
    quaternions = [TOOL_DOWN, (0.92388, 0.38268, 0.0, 0.0), (0.92388, 0.0, 0.38268, 0.0),
                   (0.92388, 0.0, 0.0, 0.38268)]
    mass, com = 1.5, np.array([0.0, 0.0, 0.08])
    readings = []
    for q in quaternions:
        g = quaternion_to_matrix(q).T @ np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2 * mass])
        readings.append(np.concatenate([g, np.cross(com, g)]) + rng.normal(scale=1e-3, size=6))
    tool = fit_tool_load(quaternions, np.array(readings), names=["a", "b", "c", "d"],
                         samples=[100] * 4)
    noise = estimate_noise(rng.normal(scale=0.2, size=(200, 6)), np.arange(200) * 1e-3)
    check = MatrixCheck(12, tuple(tuple(float(i == j) for j in range(6)) for i in range(6)),
                        (0.01,) * 6, (0.02,) * 6)
    sensor = SensorInfo("JR3 67M25 😀", "SN-1", 1, (200.0, 200.0, 400.0, 20.0, 20.0, 20.0),
                        125.0, "emulator")
    return Calibration("2024-05-01T12:00:00+00:00", sensor, noise, tool, check)


def calibration_case(folder: Path) -> FileCase:
    """A calibration with every section filled (:func:`filled_calibration`), saved to ``folder``."""
    from forcelearn.calibration import load_calibration, save_calibration
    from forcelearn.errors import ConfigError

    cal = filled_calibration()
    path = folder / "calibration.toml"
    save_calibration(cal, path)
    return FileCase(path.read_bytes(), cal, folder / "mutant.toml", load_calibration,
                    lambda a, b: a == b, ConfigError)


def calibration_values_case(folder: Path) -> FileCase:
    """The calibration, with odd values and a recomputed digest: only property 1 holds."""
    case = calibration_case(folder)
    return FileCase(case.good, None, folder / "mutant-values.toml", case.load, case.same,
                    case.error, compare=False,
                    extra={"mutant": lambda rng, good: calibration_value_mutant(rng, good,
                                                                                odd_value)})


def config_case(folder: Path, example: Path) -> FileCase:
    """An example cell config: only the no-foreign-exception property is checked."""
    from forcelearn.errors import ConfigError
    from forcelearn.site.config import load_cell_config

    def load(path: Path) -> object:
        return load_cell_config(path)

    return FileCase(example.read_bytes(), None, folder / "mutant-cell.toml", load,
                    lambda a, b: True, ConfigError, compare=False)


def file_mutations(rng: random.Random, case: FileCase) -> list[Mutation]:
    """Mutations for a file: for text files, digit changes are frequent."""
    mutations = random_mutations(rng, 3)
    if case.path.suffix == ".toml" and rng.random() < 0.5:
        digits = [i for i, b in enumerate(case.good) if 0x30 <= b <= 0x39]
        at = rng.choice(digits)
        mutations = [(1, at, 0x30 + rng.randrange(10))]
    return mutations
