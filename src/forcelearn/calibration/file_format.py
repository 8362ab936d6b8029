"""The calibration file: versioned TOML, written atomically by a small serializer, read strictly.

The standard library reads TOML (``tomllib``) but does not write it; the file
holds only strings, integers, finite floats, arrays of them and one array of
tables, so :func:`dumps` covers exactly that rather than adding a dependency.

The reader refuses any other ``format_version``, unknown or missing keys,
wrong lengths, non-finite numbers, a covariance that is not symmetric
positive semi-definite with positive variances, a non-positive mass and
non-unit quaternions; every message names the key. The table of keys is in
docs/calibration.md.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from forcelearn.atomic import atomic_write_bytes
from forcelearn.calibration.model import (
    FORMAT_VERSION,
    Calibration,
    MatrixCheck,
    NoiseEstimate,
    PoseFit,
    SensorInfo,
    ToolLoad,
)
from forcelearn.config import read_toml
from forcelearn.errors import ConfigError

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


# ---- writing ----------------------------------------------------------------------------
def _key(key: str) -> str:
    return key if _BARE_KEY.match(key) else json.dumps(key)


def _value(value: Any, indent: str = "") -> str:
    """Return one TOML value: bool, int, finite float, str, or arrays of them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        if not math.isfinite(value):
            raise ValueError(f"TOML has no {value}: only finite floats are written")
        return repr(float(value))
    if isinstance(value, str):
        return json.dumps(value)  # JSON's escapes are valid in a TOML basic string
    if isinstance(value, Sequence | np.ndarray):
        items = list(value)
        if items and all(isinstance(v, Sequence | np.ndarray) for v in items):
            inner = indent + "    "
            rows = "".join(f"{inner}{_value(v, inner)},\n" for v in items)
            return f"[\n{rows}{indent}]"
        return "[" + ", ".join(_value(v, indent) for v in items) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def dumps(document: Mapping[str, Any], header: str = "") -> str:
    """Serialise nested dicts to TOML; a list of dicts is an array of tables (scalars only)."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    _write_table(lines, [], document)
    return "\n".join(lines).strip("\n") + "\n"


def _write_table(lines: list[str], path: list[str], table: Mapping[str, Any]) -> None:
    def is_table_array(v: Any) -> bool:
        return isinstance(v, list) and bool(v) and all(isinstance(i, Mapping) for i in v)

    for key, value in table.items():
        if value is not None and not isinstance(value, Mapping) and not is_table_array(value):
            lines.append(f"{_key(key)} = {_value(value)}")
    for key, value in table.items():
        dotted = ".".join(_key(k) for k in [*path, key])
        if isinstance(value, Mapping):
            lines += ["", f"[{dotted}]"]
            _write_table(lines, [*path, key], value)
        elif is_table_array(value):
            for item in value:
                if any(isinstance(v, Mapping) or is_table_array(v) for v in item.values()):
                    raise TypeError(f"{dotted}: tables inside an array of tables are not written")
                lines += ["", f"[[{dotted}]]"]
                _write_table(lines, [*path, key], item)


def to_document(cal: Calibration) -> dict[str, Any]:
    """Return the calibration as the nested dict that :func:`dumps` writes."""
    s, n, t = cal.sensor, cal.noise, cal.tool
    doc: dict[str, Any] = {
        "format_version": cal.format_version,
        "created": cal.created,
        "sensor": {"model": s.model, "serial": s.serial, "node_id": s.node_id,
                   "full_scales": s.full_scales, "cutoff_hz": s.cutoff_hz, "robot": s.robot},
        "noise": {"bias": n.bias, "covariance": n.covariance, "drift_per_s": n.drift_per_s,
                  "samples": n.samples, "duration_s": n.duration_s, "rate_hz": n.rate_hz,
                  "zero_quaternion": n.zero_quaternion},
        "tool": {
            "mass_kg": t.mass_kg, "mass_std_kg": t.mass_std_kg,
            "com_mm": t.com_mm, "com_std_mm": t.com_std_mm,
            "force_bias_n": t.force_bias_n, "force_bias_std_n": t.force_bias_std_n,
            "torque_bias_nm": t.torque_bias_nm, "torque_bias_std_nm": t.torque_bias_std_nm,
            "condition_number": t.condition_number,
            "pose": [{"name": p.name, "quaternion": p.quaternion, "samples": p.samples,
                      "mean": p.mean, "residual": p.residual} for p in t.poses],
        },
    }
    if cal.matrix_check is not None:
        m = cal.matrix_check
        doc["matrix_check"] = {"loads": m.loads, "matrix": m.matrix,
                               "rms_residual_fit": m.rms_residual_fit,
                               "rms_residual_sensor": m.rms_residual_sensor}
    return doc


def to_toml(cal: Calibration) -> str:
    """Return the calibration file's text."""
    t = cal.tool
    header = (
        "forcelearn sensor calibration, written by `forcelearn calibrate` "
        "(see docs/calibration.md)\n"
        "units: N, N*m, kg, mm, s, Hz; wrenches Fx Fy Fz Mx My Mz in the sensor frame;\n"
        "quaternions (w, x, y, z) sensor frame -> world, world z up\n"
        f"tool {t.mass_kg:.4f} +- {t.mass_std_kg:.4f} kg, centre of mass "
        f"{[round(c, 2) for c in t.com_mm]} mm; noise std "
        f"{[float(f'{v:.3g}') for v in cal.noise.std]}"
    )
    return dumps(to_document(cal), header)


def save_calibration(cal: Calibration, path: str | os.PathLike[str]) -> None:
    """Write the calibration file atomically (a reader sees the old file or the new one)."""
    atomic_write_bytes(path, to_toml(cal).encode("utf-8"))


# ---- reading ----------------------------------------------------------------------------
class _Table:
    """Typed access to one TOML table; errors name ``section.key``; :meth:`done` refuses extras."""

    def __init__(self, data: Any, name: str, source: str) -> None:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: [{name}] must be a table")
        self.data, self.name, self.source, self.used = data, name, source, set()

    def _get(self, key: str) -> Any:
        self.used.add(key)
        if key not in self.data:
            raise ConfigError(f"{self.source}: missing key {self.name}.{key}")
        return self.data[key]

    def fail(self, key: str, why: str) -> ConfigError:
        return ConfigError(f"{self.source}: {self.name}.{key} {why}")

    def string(self, key: str) -> str:
        value = self._get(key)
        if not isinstance(value, str):
            raise self.fail(key, f"must be a string, got {value!r}")
        return value

    def integer(self, key: str, minimum: int = 0) -> int:
        value = self._get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise self.fail(key, f"must be an integer >= {minimum}, got {value!r}")
        return value

    def number(self, key: str, minimum: float = -math.inf, above: bool = False) -> float:
        value = self._get(key)
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if not ok or not math.isfinite(value) or value < minimum or (above and value == minimum):
            bound = f" {'>' if above else '>='} {minimum:g}" if minimum > -math.inf else ""
            raise self.fail(key, f"must be a finite number{bound}, got {value!r}")
        return float(value)

    def vector(self, key: str, length: int, minimum: float = -math.inf) -> tuple[float, ...]:
        value = self._get(key)
        if not isinstance(value, list) or len(value) != length or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            and v >= minimum for v in value
        ):
            extra = f" >= {minimum:g}" if minimum > -math.inf else ""
            raise self.fail(key, f"must be {length} finite numbers{extra}, got {value!r}")
        return tuple(float(v) for v in value)

    def matrix(self, key: str, size: int) -> tuple[tuple[float, ...], ...]:
        value = self._get(key)
        if not isinstance(value, list) or len(value) != size:
            raise self.fail(key, f"must be {size} rows of {size} numbers")
        return tuple(_Table({key: row}, self.name, self.source).vector(key, size)
                     for row in value)

    def quaternion(self, key: str) -> tuple[float, float, float, float]:
        q = self.vector(key, 4)
        if abs(math.sqrt(sum(c * c for c in q)) - 1.0) > 1e-3:
            raise self.fail(key, f"must be a unit quaternion (w, x, y, z), got {list(q)}")
        return q  # type: ignore[return-value]

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise ConfigError(
                f"{self.source}: unknown key(s) {', '.join(f'{self.name}.{k}' for k in unknown)}"
            )


def from_document(data: Mapping[str, Any], source: str = "calibration") -> Calibration:
    """Build a :class:`Calibration` from a parsed TOML document, checking every key."""
    version = data.get("format_version")
    if version != FORMAT_VERSION:
        raise ConfigError(
            f"{source}: format_version is {version!r}, this forcelearn reads version "
            f"{FORMAT_VERSION}; run `forcelearn calibrate` again to write a current file"
        )
    top = _Table(data, "file", source)
    top.used.add("format_version")
    created = top.string("created")
    s = _Table(top._get("sensor"), "sensor", source)
    sensor = SensorInfo(model=s.string("model"), serial=s.string("serial"),
                        node_id=s.integer("node_id", 1), full_scales=s.vector("full_scales", 6),
                        cutoff_hz=s.number("cutoff_hz", 0.0), robot=s.string("robot"))
    s.done()
    n = _Table(top._get("noise"), "noise", source)
    noise = NoiseEstimate(
        bias=n.vector("bias", 6), covariance=n.matrix("covariance", 6),
        drift_per_s=n.vector("drift_per_s", 6), samples=n.integer("samples", 10),
        duration_s=n.number("duration_s", 0.0), rate_hz=n.number("rate_hz", 0.0),
        zero_quaternion=n.quaternion("zero_quaternion"),
    )
    n.done()
    cov = np.asarray(noise.covariance)
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-15):
        raise n.fail("covariance", "must be symmetric")
    if np.any(np.diag(cov) <= 0) or np.linalg.eigvalsh(cov)[0] < -1e-9 * np.max(np.diag(cov)):
        raise n.fail("covariance", "must be positive semi-definite with variances > 0")
    tool = _read_tool(_Table(top._get("tool"), "tool", source), source)
    check = None
    if "matrix_check" in data:
        c = _Table(top._get("matrix_check"), "matrix_check", source)
        check = MatrixCheck(loads=c.integer("loads", 12), matrix=c.matrix("matrix", 6),
                            rms_residual_fit=c.vector("rms_residual_fit", 6, 0.0),
                            rms_residual_sensor=c.vector("rms_residual_sensor", 6, 0.0))
        c.done()
    top.done()
    return Calibration(created=created, sensor=sensor, noise=noise, tool=tool,
                       matrix_check=check)


def _read_tool(t: _Table, source: str) -> ToolLoad:
    raw_poses = t._get("pose")
    if not isinstance(raw_poses, list) or not raw_poses:
        raise t.fail("pose", "must be an array of tables [[tool.pose]], one per orientation")
    poses = []
    for i, raw in enumerate(raw_poses):
        p = _Table(raw, f"tool.pose[{i}]", source)
        poses.append(PoseFit(name=p.string("name"), quaternion=p.quaternion("quaternion"),
                             samples=p.integer("samples"), mean=p.vector("mean", 6),
                             residual=p.vector("residual", 6)))
        p.done()
    tool = ToolLoad(
        mass_kg=t.number("mass_kg", 0.0, above=True), mass_std_kg=t.number("mass_std_kg", 0.0),
        com_mm=t.vector("com_mm", 3), com_std_mm=t.vector("com_std_mm", 3, 0.0),
        force_bias_n=t.vector("force_bias_n", 3),
        force_bias_std_n=t.vector("force_bias_std_n", 3, 0.0),
        torque_bias_nm=t.vector("torque_bias_nm", 3),
        torque_bias_std_nm=t.vector("torque_bias_std_nm", 3, 0.0),
        condition_number=t.number("condition_number", 1.0), poses=tuple(poses),
    )
    t.done()
    return tool


def load_calibration(path: str | os.PathLike[str]) -> Calibration:
    """Read and check a calibration file; ConfigError names the file and the key."""
    return from_document(read_toml(path), f"calibration file {os.fspath(path)!r}")
