"""The grid of a study: ``--set key=v1,v2`` lists, their product, and one run spec per seed.

Keys are dotted paths into the task's config dataclass (``learner.gamma``,
``task.theta1_parts``, ``geometry.stiffness_n_per_m``, ``emulator.sponge...``);
a bare field name that is unique in the config (``gamma``) stands for its path,
and ``d`` for ``learner.extent``. Values are typed by the default they replace:
``true``/``false`` for booleans, and for tuples ``a:b`` (one element per
dimension) or a single value repeated for every dimension (``d=5`` is (5, 5)).
A key whose default is unset (``None``, such as ``task.tolerance_n`` or
``cma.sigma0_mm``) is typed by its field's annotation, and ``none`` keeps it unset.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import typing
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from forcelearn.errors import ConfigError

ALIASES = {"d": "learner.extent"}
"""Short names for keys users sweep often."""
RESERVED = {"trials", "seed", "source", "calibration_file"}
"""Top-level fields the study sets itself (or that are not parameters)."""

Value = bool | int | float | str | tuple[Any, ...] | None


def _leaves(config: Any, prefix: str = "") -> Iterator[tuple[str, Any, Any]]:
    """Every settable leaf of a nested config dataclass: (dotted.key, value, annotation)."""
    hints = typing.get_type_hints(type(config))
    for f in dataclasses.fields(config):
        if not f.init or (not prefix and f.name in RESERVED):
            continue
        value = getattr(config, f.name)
        path = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            yield from _leaves(value, path + ".")
        else:
            yield path, value, hints.get(f.name)


def leaf_keys(config: Any) -> dict[str, Any]:
    """Return every settable leaf of a nested config dataclass as ``{dotted.key: value}``."""
    return {path: value for path, value, _ in _leaves(config)}


def resolve_key(config: Any, key: str) -> str:
    """Return the full dotted path of ``key`` in ``config``.

    Raises:
        ConfigError: the key is unknown or ambiguous; the message lists the valid keys.
    """
    known = leaf_keys(config)
    key = ALIASES.get(key, key)
    if key in known:
        return key
    matches = [k for k in known if k.rsplit(".", 1)[-1] == key]
    if len(matches) == 1:
        return matches[0]
    if matches:
        raise ConfigError(f"--set key {key!r} is ambiguous: write one of {', '.join(matches)}")
    raise ConfigError(
        f"unknown --set key {key!r}; valid keys: {', '.join(sorted(known))} "
        f"(aliases: {', '.join(f'{a} = {k}' for a, k in ALIASES.items())})"
    )


def parse_value(key: str, text: str, default: Any, hint: Any = None) -> Value:
    """Parse one ``--set`` value for ``key``, typed like its ``default``.

    An unset default (None) is typed by the field's annotation ``hint``
    (``float | None``...); ``none`` keeps it unset.
    """
    text = text.strip()
    if default is None:
        if text.lower() == "none":
            return None
        default = _example_of(hint)
    try:
        if isinstance(default, bool):
            lowered = text.lower()
            if lowered not in ("true", "false", "1", "0"):
                raise ValueError("expected true or false")
            return lowered in ("true", "1")
        if isinstance(default, tuple):
            parts = text.split(":")
            if len(parts) == 1 and default:
                parts = parts * len(default)
            element = default[0] if default else ""
            return tuple(parse_value(key, p, element) for p in parts)
        if isinstance(default, int):
            return int(text)
        if isinstance(default, float):
            return float(text)
    except ValueError as exc:
        raise ConfigError(f"--set {key}: cannot read {text!r} ({exc})") from exc
    return text


def _example_of(hint: Any) -> Any:
    """A value of the type an optional field holds when set (text when unknown)."""
    kinds = [a for a in typing.get_args(hint) if a is not type(None)] or [hint]
    kind = kinds[0]
    if typing.get_origin(kind) is tuple:
        return (_example_of((typing.get_args(kind) or (str,))[0]),)
    examples: dict[Any, Any] = {bool: False, int: 0, float: 0.0}
    return examples.get(kind, "")


def format_value(value: Any) -> str:
    """Write a value back in ``--set`` syntax (tuples as ``a:b``)."""
    if isinstance(value, tuple):
        return ":".join(format_value(v) for v in value)
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def parse_sets(config: Any, sets: Sequence[str]) -> dict[str, list[Value]]:
    """Parse ``key=v1,v2,...`` strings into ``{dotted.key: [values]}`` (in the order given)."""
    grid: dict[str, list[Value]] = {}
    leaves = {path: (value, hint) for path, value, hint in _leaves(config)}
    for item in sets:
        key, sep, values = item.partition("=")
        if not sep or not values.strip():
            raise ConfigError(f"--set {item!r}: write key=value1,value2,...")
        path = resolve_key(config, key.strip())
        if path in grid:
            raise ConfigError(f"--set {path} is given twice; list all its values in one --set")
        default, hint = leaves[path]
        grid[path] = [parse_value(path, v, default, hint) for v in values.split(",")]
    return grid


def apply_overrides(config: Any, overrides: Mapping[str, Any]) -> Any:
    """Return ``config`` with each ``dotted.key`` replaced (nested dataclasses via ``replace``)."""
    for key, value in overrides.items():
        config = _replace_path(config, key.split("."), value)
    return config


def _replace_path(node: Any, path: list[str], value: Any) -> Any:
    head, *rest = path
    new = value if not rest else _replace_path(getattr(node, head), rest, value)
    return dataclasses.replace(node, **{head: new})


def grid_points(grid: Mapping[str, Sequence[Value]]) -> list[dict[str, Value]]:
    """The product of the value lists, as one overrides dict per grid point."""
    keys = list(grid)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]


@dataclass(frozen=True)
class RunSpec:
    """One run of a study: a grid point and a seed."""

    task: str
    trials: int
    seed: int
    overrides: tuple[tuple[str, Value], ...]
    """The grid point, as ``(dotted.key, value)`` pairs in --set order."""

    @property
    def run_id(self) -> str:
        """A stable name for the run: the same task, trials, point and seed give the same id."""
        canonical = json.dumps(
            [
                self.task,
                self.trials,
                self.seed,
                sorted((k, format_value(v)) for k, v in self.overrides),
            ]
        )
        return hashlib.sha1(canonical.encode()).hexdigest()[:16]


def run_specs(
    task: str, trials: int, seeds: Sequence[int], points: Sequence[Mapping[str, Value]]
) -> Iterator[RunSpec]:
    """Every (point, seed) pair as a :class:`RunSpec`, point by point."""
    for point in points:
        for seed in seeds:
            yield RunSpec(task, trials, seed, tuple(point.items()))


CURVES = "_curves"
"""Row key of per-trial arrays; the study saves them as runs/<run_id>.npz, not in the table."""
SUMMARY_SKIP = {"task", "seed", "trials"}
"""Summary keys already in the row's identity columns."""


def result_row(spec: RunSpec, config: Any, summary: dict[str, Any]) -> dict[str, Any]:
    """One tidy row: identity, every parameter of the resolved config, every summary figure."""
    row: dict[str, Any] = {
        "run_id": spec.run_id,
        "task": spec.task,
        "seed": spec.seed,
        "trials": spec.trials,
    }
    row.update({k: format_value(v) for k, v in leaf_keys(config).items()})
    for key, value in summary.items():
        if key in SUMMARY_SKIP or isinstance(value, list):
            continue  # lists (probe fits, warnings) stay in the run's own summary.json
        if isinstance(value, dict):  # e.g. the output map: one column per scalar field
            row.update(
                {f"{key}.{k}": v for k, v in value.items() if not isinstance(v, dict | list)}
            )
        else:
            row[key] = value
    return row
