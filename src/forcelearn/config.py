"""TOML configuration into frozen dataclasses, validated at load with messages naming the key."""

from __future__ import annotations

import dataclasses
import os
import tomllib
from collections.abc import Mapping
from typing import Any, TypeVar

from forcelearn.errors import ConfigError

T = TypeVar("T")


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
    for key, value in table.items():
        if isinstance(value, list):
            table[key] = _tuples(value)
    try:
        return cls(**table)
    except ConfigError as exc:
        raise ConfigError(f"[{section}] {exc}") from exc
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"[{section}] invalid value: {exc}") from exc


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
    return int(run.get("trials", default_trials)), int(run.get("seed", 0))


def check_sections(data: Mapping[str, Any], allowed: set[str]) -> None:
    """Refuse top-level tables this config does not know, naming them."""
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ConfigError(f"unknown section(s) {unknown}; known: {sorted(allowed)}")
