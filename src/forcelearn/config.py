"""TOML configuration into frozen dataclasses, validated at load with messages naming the key."""

from __future__ import annotations

import dataclasses
import os
import tomllib
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from forcelearn.errors import ConfigError

T = TypeVar("T")

MAX_DURATION_S = 86_400.0
"""Longest time (s) any ``*_s`` setting may be: longer ones overflow the OS's timers."""


def read_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a TOML file; a missing, unreadable or malformed file is a ConfigError naming it."""
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError as exc:
        raise ConfigError(f"config file {os.fspath(path)!r} does not exist") from exc
    except IsADirectoryError as exc:
        raise ConfigError(f"config file {os.fspath(path)!r} is a directory, not a file") from exc
    except OSError as exc:
        raise ConfigError(f"config file {os.fspath(path)!r} cannot be read: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"config file {os.fspath(path)!r} is not UTF-8 text (byte {exc.start}): "
            "the file is damaged or not a TOML file"
        ) from exc
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ConfigError(f"config file {os.fspath(path)!r} is not valid TOML: {exc}") from exc


def build(cls: type[T], table: Mapping[str, Any] | None, section: str) -> T:
    """Build dataclass ``cls`` from a TOML table; errors name ``section.key``."""
    table = dict(table or {})
    known = {f.name: f for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    unknown = sorted(set(table) - set(known))
    if unknown:
        raise ConfigError(
            f"unknown key(s) {', '.join(f'{section}.{k}' for k in unknown)}; "
            f"known keys of [{section}]: {', '.join(sorted(known))}"
        )
    hints = _hints(cls)
    for key, value in table.items():
        if isinstance(value, list):
            table[key] = _tuples(value)
        _check_value(f"{section}.{key}", table[key], _default_of(known[key]))
        if key.endswith("_s") and _is_number(table[key]) and not abs(table[key]) <= MAX_DURATION_S:
            raise ConfigError(f"{section}.{key} = {table[key]!r}: a time of at most "
                              f"{MAX_DURATION_S:g} s (a day)")
        if key in hints and _matches(table[key], hints[key]) is False:
            raise ConfigError(
                f"{section}.{key} = {table[key]!r}: must be {_describe(hints[key])}"
            )
    try:
        return cls(**table)
    except ConfigError as exc:
        raise ConfigError(f"[{section}] {exc}") from exc
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"[{section}] invalid value: {exc}") from exc


def _hints(cls: type[Any]) -> dict[str, Any]:
    """The resolved annotations of ``cls``'s fields ({} where they cannot be resolved)."""
    try:
        return typing.get_type_hints(cls)
    except (NameError, TypeError):
        return {}


_PLAIN: dict[Any, tuple[Callable[[Any], bool], str]] = {
    bool: (lambda v: isinstance(v, bool), "true or false"),
    int: (lambda v: isinstance(v, int) and not isinstance(v, bool), "a whole number"),
    float: (lambda v: _is_number(v), "a number"),
    str: (lambda v: isinstance(v, str), "text"),
    type(None): (lambda v: v is None, "unset"),
}
"""Each plain annotation: its check of a TOML value, and its name in messages."""


def _matches(value: Any, hint: Any) -> bool | None:
    """Whether a TOML value fits a field's annotation; None where it cannot be told here.

    Only plain types, their unions and tuples are checked; Literal values and
    ranges are the dataclasses' own checks (with their own messages).
    """
    if hint in _PLAIN:
        return _PLAIN[hint][0](value)
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        verdicts = [_matches(value, arg) for arg in typing.get_args(hint)]
        if any(v is True for v in verdicts):
            return True
        return False if all(v is False for v in verdicts) else None
    if origin is tuple:
        if not isinstance(value, tuple):
            return False
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            items = [_matches(item, args[0]) for item in value]
        elif args:
            if len(value) != len(args):
                return False
            items = [_matches(item, arg) for item, arg in zip(value, args, strict=True)]
        else:
            return True
        if any(v is False for v in items):
            return False
        return True if all(v is True for v in items) else None
    return None


def _describe(hint: Any) -> str:
    """A field's annotation in words: 'a number', 'true or false', 'a number or unset'..."""
    if hint in _PLAIN:
        return _PLAIN[hint][1]
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list, each item {_describe(args[0])}"
        if args:
            return f"a list of {len(args)}: " + ", ".join(_describe(arg) for arg in args)
        return "a list"
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return " or ".join(_describe(arg) for arg in typing.get_args(hint))
    return str(hint)


def _default_of(f: dataclasses.Field[Any]) -> Any:
    """A field's default value (calling its factory), or MISSING."""
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _check_value(key: str, value: Any, default: Any) -> None:
    """Refuse NaN anywhere, and a non-number where the default is a number, naming ``key``."""
    if isinstance(value, float) and value != value:
        raise ConfigError(f"{key} = nan: not a number; give a finite value")
    if isinstance(value, tuple):
        for i, item in enumerate(value):
            inner = default[i] if isinstance(default, tuple) and i < len(default) else None
            _check_value(f"{key}[{i}]", item, inner)
        return
    if _is_number(default) and not _is_number(value):
        raise ConfigError(f"{key} = {value!r}: must be a number (like {default!r})")


def _tuples(value: Any) -> Any:
    """TOML arrays (nested too) as tuples, so frozen configs compare equal to their defaults."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def read_run_table(data: Mapping[str, Any], default_trials: int) -> tuple[int, int]:
    """Return (trials, seed) from the ``[run]`` table; an unknown key is named."""
    run = dict(data.get("run", {}))
    unknown = sorted(set(run) - {"trials", "seed"})
    if unknown:
        raise ConfigError(
            f"unknown key(s) {['run.' + k for k in unknown]}; known: run.trials, run.seed"
        )
    values = {"trials": run.get("trials", default_trials), "seed": run.get("seed", 0)}
    for key, value in values.items():
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"run.{key} = {value!r}: must be a whole number")
    if values["trials"] < 1:
        raise ConfigError(f"run.trials = {values['trials']}: must be >= 1")
    if values["seed"] < 0:
        raise ConfigError(f"run.seed = {values['seed']}: must be >= 0")
    return values["trials"], values["seed"]


def check_sections(data: Mapping[str, Any], allowed: set[str]) -> None:
    """Refuse top-level tables this config does not know, naming them."""
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ConfigError(f"unknown section(s) {unknown}; known: {sorted(allowed)}")
