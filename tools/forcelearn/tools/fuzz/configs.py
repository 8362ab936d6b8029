"""The ``values`` and ``runs`` fuzz targets' inputs: cell configs with odd settings.

:func:`value_mutant` replaces one to three settings of a parsed example config
by an :func:`odd_value` (another type, a table, NaN, inf, zero, a sign flip, a
huge number); :func:`check_run` runs a loading mutant for 2 trials in its own
process and asks that it ends or stops with forcelearn's one-line message.
"""

from __future__ import annotations

import random
import sys
from pathlib import Path
from typing import Any

from forcelearn.tools.fuzz.harness import FuzzFailure

ODD_VALUES: tuple[object, ...] = ("", "nonsense", [], [1, 2], {"a": 1}, True, False, 0, -1,
                                 0.0, 1e-12, 1e12, -1e12, float("nan"), float("inf"),
                                 float("-inf"), 2**63 - 1)
"""Replacement values of the ``values`` target (besides scaled copies of the setting's own)."""


def _config_leaves(table: dict[str, Any], path: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    leaves: list[tuple[str, ...]] = []
    for key, value in table.items():
        if isinstance(value, dict):
            leaves.extend(_config_leaves(value, (*path, key)))
        else:
            leaves.append((*path, key))
    return leaves


def odd_value(rng: random.Random, value: object) -> object:
    """An odd replacement for a setting: one of :data:`ODD_VALUES`, or its own value scaled."""
    if isinstance(value, int | float) and not isinstance(value, bool) and rng.random() < 0.4:
        scaled = value * rng.choice((-1, 0, 0.1, 10, 1000)) if value else rng.choice((-1, 1e6))
        return int(scaled) if isinstance(value, int) else float(scaled)
    if isinstance(value, list) and value and rng.random() < 0.4:
        items = list(value)
        items[rng.randrange(len(items))] = odd_value(rng, items[0])
        return items if rng.random() < 0.7 else items[:-1]
    return rng.choice(ODD_VALUES)


def value_mutant(rng: random.Random, good: bytes, changes: list[str] | None = None) -> bytes:
    """A parsed config with one to three settings replaced by :func:`odd_value`, as TOML.

    ``changes``, if given, receives each replacement as ``"key = value"``.
    """
    import tomllib

    import tomli_w

    data = tomllib.loads(good.decode())
    for path in rng.sample(_config_leaves(data), rng.randint(1, 3)):
        table = data
        for key in path[:-1]:
            table = table[key]
        table[path[-1]] = odd_value(rng, table[path[-1]])
        if changes is not None:
            changes.append(f"{'.'.join(path)} = {table[path[-1]]!r}")
    return tomli_w.dumps(data).encode()


RUN_TIMEOUT_S = 180.0
"""Longest a fuzzed 2-trial run may take before it counts as hung."""


def loading_value_mutant(rng: random.Random, good: bytes, folder: Path) -> tuple[Path, str]:
    """Write a :func:`value_mutant` of ``good`` that ``load_cell_config`` accepts.

    Returns its path and its changes, ``"key = value; ..."``.
    """
    from forcelearn.errors import ConfigError
    from forcelearn.site.config import load_cell_config

    path = folder / "run-cell.toml"
    while True:
        changes: list[str] = []
        path.write_bytes(value_mutant(rng, good, changes))
        try:
            load_cell_config(path)
            return path, "; ".join(changes)
        except ConfigError:
            continue


def emulated_example(example: Path) -> bool:
    """Whether a config runs on the built-in emulated cell (robot and sensor)."""
    from forcelearn.errors import ConfigError
    from forcelearn.site.config import load_cell_config

    try:
        config = load_cell_config(example)
    except ConfigError:
        return False
    return config.robot_emulated and config.sensor_emulated


def check_run(config: Path, out: Path, changes: str = "") -> str:
    """``forcelearn run`` of 2 trials in a child process: "ran", "stopped", or a FuzzFailure.

    ``changes`` (what differs from the example) goes into a failure's message.
    """
    import shutil
    import subprocess

    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, "-m", "forcelearn.tools.cli", "run", "--config", str(config),
               "--trials", "2", "--no-progress", "--out", str(out)]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        raise FuzzFailure(f"a run with {changes or config.name} raised a hang: no end within "
                          f"{RUN_TIMEOUT_S:g} s") from exc
    last = (done.stderr.strip().splitlines() or [""])[-1]
    if "Traceback" in done.stderr or done.returncode not in (0, 1, 3):
        raise FuzzFailure(f"a run with {changes or config.name} raised exit "
                          f"{done.returncode}: {last}")
    return "ran" if done.returncode in (0, 3) else "stopped"
