"""The calibration file: versioned TOML with an integrity digest, written atomically, read strictly.

Written with ``tomli-w`` (the standard library reads TOML but does not write
it), read with ``tomllib``. Format version 2 adds ``digest`` (SHA-256 of the
canonical content, see :func:`content_digest`) and ``tool.pose_count``, so a
file that was damaged, truncated or edited after it was written is refused
instead of loading wrong values. Version 3 adds the sensor's mounting on the
flange (``tool.mounting_quaternion``, ``mounting_std_deg``, ``mounting_source``).

The reader refuses any other ``format_version``, unknown or missing keys,
wrong lengths, non-finite numbers, implausible full scales, a node id outside
1..127, a cut-off <= 0, a covariance that is not symmetric positive
semi-definite with positive variances, a non-positive mass, non-unit
quaternions, a pose count that disagrees with the poses, a digest that
disagrees with the content, and (beside the digest, which proves only that the
file is the one written) any value beyond its physical bound
(:mod:`.bounds`: a cut-off above 10 kHz, a tool heavier than the sensor can
weigh, a bias beyond the full scale...); every message names the key. The table of keys
is in docs/calibration.md.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tomllib
from collections.abc import Mapping
from typing import Any

import numpy as np
import tomli_w

from forcelearn.atomic import atomic_write_bytes
from forcelearn.calibration.bounds import check_bounds
from forcelearn.calibration.model import (
    FORMAT_VERSION,
    MOUNTING_ESTIMATED,
    MOUNTING_GIVEN,
    Calibration,
    MatrixCheck,
    NoiseEstimate,
    PoseFit,
    SensorInfo,
    ToolLoad,
)
from forcelearn.config import read_toml
from forcelearn.devices import check_full_scales
from forcelearn.errors import ConfigError

DIGEST_PREFIX = "sha256:"
READABLE_VERSIONS = (2, 3)
"""Versions read: 3 (this one) and 2 (no mounting keys: the sensor's axes are the flange's)."""
MAX_NODE_ID = 127
"""CAN node ids are 1..127."""


# ---- writing ----------------------------------------------------------------------------
def _plain(value: Any) -> Any:
    """Return ``value`` as plain TOML types (numpy scalars and tuples converted, floats finite)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        if not math.isfinite(value):
            raise ValueError(f"TOML has no {value}: only finite floats are written")
        return float(value)
    if isinstance(value, str):
        return value
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple | np.ndarray):
        return [_plain(v) for v in value]
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def dumps(document: Mapping[str, Any], header: str = "") -> str:
    """Serialise nested dicts to TOML with tomli-w, ``header`` as leading comment lines."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    body = tomli_w.dumps(_plain(document), indent=4)
    return "\n".join([*lines, ""]) + body if lines else body


def content_digest(document: Mapping[str, Any]) -> str:
    """Return ``"sha256:<hex>"`` of the document's canonical JSON, ``digest`` key left out.

    Canonical: keys sorted, no spaces, UTF-8, floats as Python's shortest repr,
    which TOML reproduces exactly, so a written file and its parsed content
    give the same digest.
    """
    content = {k: v for k, v in document.items() if k != "digest"}
    text = json.dumps(_plain(content), sort_keys=True, separators=(",", ":"),
                      ensure_ascii=False, allow_nan=False)
    return DIGEST_PREFIX + hashlib.sha256(text.encode("utf-8")).hexdigest()


def to_document(cal: Calibration) -> dict[str, Any]:
    """Return the calibration as the nested dict that :func:`dumps` writes."""
    s, n, t = cal.sensor, cal.noise, cal.tool
    doc: dict[str, Any] = {
        "format_version": FORMAT_VERSION,  # a version 2 read is written as 3
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
            "mounting_quaternion": t.mounting_quaternion,
            "mounting_std_deg": t.mounting_std_deg, "mounting_source": t.mounting_source,
            "pose_count": len(t.poses),
            "pose": [{"name": p.name, "quaternion": p.quaternion, "samples": p.samples,
                      "mean": p.mean, "residual": p.residual} for p in t.poses],
        },
    }
    if cal.matrix_check is not None:
        m = cal.matrix_check
        doc["matrix_check"] = {"loads": m.loads, "matrix": m.matrix,
                               "rms_residual_fit": m.rms_residual_fit,
                               "rms_residual_sensor": m.rms_residual_sensor}
    doc["digest"] = content_digest(doc)
    return doc


def to_toml(cal: Calibration) -> str:
    """Return the calibration file's text."""
    t = cal.tool
    header = (
        "forcelearn sensor calibration, written by `forcelearn calibrate` "
        "(see docs/calibration.md)\n"
        "units: N, N*m, kg, mm, s, Hz; wrenches Fx Fy Fz Mx My Mz in the sensor frame;\n"
        "quaternions (w, x, y, z) as RAPID: robot flange (tool) frame -> world, world z up;\n"
        "sensor frame = flange frame turned by tool.mounting_quaternion\n"
        f"tool {t.mass_kg:.4f} +- {t.mass_std_kg:.4f} kg, centre of mass "
        f"{[round(c, 2) for c in t.com_mm]} mm; noise std "
        f"{[float(f'{v:.3g}') for v in cal.noise.std]}"
    )
    return dumps(to_document(cal), header)


def save_calibration(cal: Calibration, path: str | os.PathLike[str]) -> None:
    """Write the calibration file atomically (a reader sees the old file or the new one).

    The text is read back and checked first, so a file that can be written can
    be read: ConfigError names what the reader would refuse, and nothing is written.
    """
    text = to_toml(cal)
    from_document(tomllib.loads(text), f"calibration to write to {os.fspath(path)!r}")
    atomic_write_bytes(path, text.encode("utf-8"))


# ---- reading ----------------------------------------------------------------------------
class _Table:
    """Typed access to one TOML table; errors name ``section.key``; :meth:`done` refuses extras."""

    def __init__(self, data: Any, name: str, source: str) -> None:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: [{name}] must be a table")
        self.data, self.name, self.source = data, name, source
        self.used: set[str] = set()

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

    def integer(self, key: str, minimum: int = 0, maximum: int | None = None) -> int:
        value = self._get(key)
        if (isinstance(value, bool) or not isinstance(value, int) or value < minimum
                or (maximum is not None and value > maximum)):
            bound = f"{minimum}..{maximum}" if maximum is not None else f">= {minimum}"
            raise self.fail(key, f"must be an integer {bound}, got {value!r}")
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
    if version not in READABLE_VERSIONS:
        raise ConfigError(
            f"{source}: format_version is {version!r}, this forcelearn reads versions "
            f"{list(READABLE_VERSIONS)}; run `forcelearn calibrate` again to write a current file"
        )
    top = _Table(data, "file", source)
    top.used.update(("format_version", "digest"))
    created = top.string("created")
    s = _Table(top._get("sensor"), "sensor", source)
    sensor = SensorInfo(model=s.string("model"), serial=s.string("serial"),
                        node_id=s.integer("node_id", 1, MAX_NODE_ID),
                        full_scales=s.vector("full_scales", 6),
                        cutoff_hz=s.number("cutoff_hz", 0.0, above=True), robot=s.string("robot"))
    try:
        check_full_scales(sensor.full_scales)
    except ValueError as exc:
        raise s.fail("full_scales", str(exc)) from None
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
    tool = _read_tool(_Table(top._get("tool"), "tool", source), source, version)
    check = None
    if "matrix_check" in data:
        c = _Table(top._get("matrix_check"), "matrix_check", source)
        check = MatrixCheck(loads=c.integer("loads", 12), matrix=c.matrix("matrix", 6),
                            rms_residual_fit=c.vector("rms_residual_fit", 6, 0.0),
                            rms_residual_sensor=c.vector("rms_residual_sensor", 6, 0.0))
        c.done()
    top.done()
    _check_digest(data, source)
    cal = Calibration(created=created, sensor=sensor, noise=noise, tool=tool,
                      matrix_check=check, format_version=version)
    check_bounds(cal, source)
    return cal


def _read_mounting(t: _Table, version: int) -> dict[str, Any]:
    """Version 3's mounting keys; a version 2 file had the sensor's axes the flange's."""
    if version < 3:
        return {}
    source = t.string("mounting_source")
    if source not in (MOUNTING_GIVEN, MOUNTING_ESTIMATED):
        raise t.fail("mounting_source", f"must be {MOUNTING_GIVEN!r} or {MOUNTING_ESTIMATED!r}, "
                     f"got {source!r}")
    return {"mounting_quaternion": t.quaternion("mounting_quaternion"),
            "mounting_std_deg": t.number("mounting_std_deg", 0.0), "mounting_source": source}


def _read_tool(t: _Table, source: str, version: int) -> ToolLoad:
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
    pose_count = t.integer("pose_count", 1)
    if pose_count != len(poses):
        raise t.fail("pose_count", f"is {pose_count} but the file holds {len(poses)} poses: it "
                     "is truncated or damaged; run `forcelearn calibrate` again")
    tool = ToolLoad(
        mass_kg=t.number("mass_kg", 0.0, above=True), mass_std_kg=t.number("mass_std_kg", 0.0),
        com_mm=t.vector("com_mm", 3), com_std_mm=t.vector("com_std_mm", 3, 0.0),
        force_bias_n=t.vector("force_bias_n", 3),
        force_bias_std_n=t.vector("force_bias_std_n", 3, 0.0),
        torque_bias_nm=t.vector("torque_bias_nm", 3),
        torque_bias_std_nm=t.vector("torque_bias_std_nm", 3, 0.0),
        condition_number=t.number("condition_number", 1.0), poses=tuple(poses),
        **_read_mounting(t, version),
    )
    t.done()
    return tool


def _check_digest(data: Mapping[str, Any], source: str) -> None:
    """Refuse a document whose ``digest`` is missing or disagrees with its content."""
    digest = data.get("digest")
    if not isinstance(digest, str) or not digest.startswith(DIGEST_PREFIX):
        raise ConfigError(f"{source}: missing key file.digest (\"{DIGEST_PREFIX}...\")")
    if digest != content_digest(data):
        raise ConfigError(
            f"{source}: file.digest does not match the content: the file was damaged, "
            "truncated or edited after it was written; run `forcelearn calibrate` again "
            "(or restore the file from a backup)"
        )


def load_calibration(path: str | os.PathLike[str]) -> Calibration:
    """Read and check a calibration file; ConfigError names the file and the key."""
    return from_document(read_toml(path), f"calibration file {os.fspath(path)!r}")
