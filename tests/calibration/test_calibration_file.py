"""The calibration file: TOML round trip, atomic write, strict reading with keys named."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from forcelearn.calibration import (
    FORMAT_VERSION,
    Calibration,
    MatrixCheck,
    SensorInfo,
    dumps,
    estimate_noise,
    fit_tool_load,
    load_calibration,
    save_calibration,
    to_toml,
)
from forcelearn.emulators.physics.cell import quaternion_to_matrix
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench
from forcelearn.errors import ConfigError
from forcelearn.tools.experiments.calibration_plan import DEFAULT_POSES


@pytest.fixture()
def calibration() -> Calibration:
    """A calibration with every section filled, from synthetic data."""
    rng = np.random.default_rng(0)
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    readings = np.array([gravity_wrench(ToolParams(), quaternion_to_matrix(q))
                         + rng.normal(scale=[0.01] * 3 + [0.001] * 3) for q in quaternions])
    tool = fit_tool_load(quaternions, readings, names=[p.name for p in DEFAULT_POSES],
                         samples=[500] * len(quaternions))
    noise = estimate_noise(rng.normal(scale=0.2, size=(200, 6)), np.arange(200) * 1e-3)
    check = MatrixCheck(12, tuple(tuple(float(i == j) for j in range(6)) for i in range(6)),
                        (0.01,) * 6, (0.02,) * 6)
    sensor = SensorInfo('JR3 "67M25" \\ test', "SN-1", 1, (200.0, 200.0, 400.0, 20.0, 20.0, 20.0),
                        125.0, "emulator")
    return Calibration("2024-05-01T12:00:00+00:00", sensor, noise, tool, check)


def test_round_trip_gives_back_the_same_calibration(tmp_path: Path, calibration) -> None:
    """Saving then loading returns an equal object (floats exact, strings escaped)."""
    path = tmp_path / "cal.toml"
    save_calibration(calibration, path)
    assert load_calibration(path) == calibration
    assert [p.name for p in tmp_path.iterdir()] == ["cal.toml"]  # no temporary file left
    text = path.read_text()
    assert text.startswith("# forcelearn sensor calibration")
    assert f"format_version = {FORMAT_VERSION}" in text
    assert "[[tool.pose]]" in text and "digest = " in text


def test_round_trip_without_the_optional_matrix_check(tmp_path: Path, calibration) -> None:
    """A calibration without [matrix_check] reads back with matrix_check None."""
    from dataclasses import replace

    plain = replace(calibration, matrix_check=None)
    save_calibration(plain, tmp_path / "c.toml")
    assert load_calibration(tmp_path / "c.toml") == plain
    assert "matrix_check" not in (tmp_path / "c.toml").read_text()


def test_a_failed_write_leaves_the_old_file_untouched(tmp_path: Path, calibration,
                                                      monkeypatch) -> None:
    """If serialising fails midway, the previous file is still there, whole."""
    path = tmp_path / "cal.toml"
    save_calibration(calibration, path)
    before = path.read_bytes()
    import forcelearn.calibration.file_format as file_format

    monkeypatch.setattr(file_format, "to_toml", lambda cal: (_ for _ in ()).throw(OSError("x")))
    with pytest.raises(OSError):
        save_calibration(calibration, path)
    assert path.read_bytes() == before


def _edit(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("format_version = 3", "format_version = 1",
         "format_version is 1.*reads versions \\[2, 3\\]"),
        ("format_version = 3", "", "format_version is None"),
        ('created = "', 'creatd = "', "missing key file.created"),
        ("[sensor]\n", "[sensor]\nextra = 1\n", "unknown key.*sensor.extra"),
        ("mass_kg = ", "mass_kg = -", "tool.mass_kg must be a finite number > 0"),
        ("com_mm = [", "com_mm = [1.0, ", "tool.com_mm must be 3 finite numbers"),
        ("rate_hz = ", "rate_hz = true #", "noise.rate_hz must be a finite number"),
        ("node_id = 1", 'node_id = "1"', "sensor.node_id must be an integer"),
        ("quaternion = [", "quaternion = [2.0, ", "must be 4 finite"),
        ("covariance = [\n    [", "covariance = [\n    [5.0, ", "noise.covariance must be 6"),
        ("[noise]\n", "[noise]\nstd = [1.0]\n", "unknown key.*noise.std"),
    ],
)
def test_bad_files_are_refused_naming_the_key(tmp_path: Path, calibration, old: str, new: str,
                                              message: str) -> None:
    """Each damaged or foreign file is a ConfigError that names the file and the key."""
    path = tmp_path / "cal.toml"
    path.write_text(_edit(to_toml(calibration), old, new))
    with pytest.raises(ConfigError, match=message) as caught:
        load_calibration(path)
    assert "cal.toml" in str(caught.value)


def test_a_covariance_that_is_not_a_covariance_is_refused(tmp_path: Path, calibration) -> None:
    """Asymmetric, zero-variance or indefinite matrices are refused: R must be > 0."""
    from dataclasses import replace

    eye = np.eye(6) * 0.04
    for matrix, message in (
        (eye + np.triu(np.ones((6, 6)), 1) * 0.01, "symmetric"),
        (np.diag([0.04] * 5 + [0.0]), "variances > 0"),
        (eye + (np.ones((6, 6)) - np.eye(6)) * 0.5, "positive semi-definite"),
    ):
        noise = replace(calibration.noise, covariance=tuple(tuple(r) for r in matrix.tolist()))
        path = tmp_path / "bad.toml"
        path.write_text(to_toml(replace(calibration, noise=noise)))
        with pytest.raises(ConfigError, match=message):
            load_calibration(path)


def test_missing_and_non_toml_files_are_config_errors(tmp_path: Path) -> None:
    """A missing file or broken TOML names the file."""
    with pytest.raises(ConfigError, match="does not exist"):
        load_calibration(tmp_path / "nope.toml")
    (tmp_path / "broken.toml").write_text("format_version = [")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_calibration(tmp_path / "broken.toml")


def test_the_serializer_writes_what_tomllib_reads_back() -> None:
    """Strings with quotes, backslashes and newlines, ints, floats, nested arrays, tables."""
    doc = {
        "s": 'a "quoted" \\ back\nslash\tand é',
        "i": 3, "f": 1e-17, "g": -2.5e300, "b": True,
        "v": [1.0, 2, -0.0], "m": [[1.0, 2.0], [3.0, 4.0]],
        "t": {"x": 1, "odd key": "y", "sub": {"z": [0.1]}},
        "rows": [{"a": 1}, {"a": 2}],
    }
    assert tomllib.loads(dumps(doc, "header\nline two")) == doc
    with pytest.raises(ValueError, match="finite"):
        dumps({"x": float("nan")})
    with pytest.raises(TypeError, match="cannot write"):
        dumps({"x": object()})


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("node_id = 1\n", "node_id = 500\n", r"sensor\.node_id must be an integer 1\.\.127"),
        ("cutoff_hz = 125.0", "cutoff_hz = 0.0", r"sensor\.cutoff_hz must be a finite number > 0"),
        ("full_scales = [\n    200.0", "full_scales = [\n    -200.0", "full_scales.*implausible"),
        ("full_scales = [\n    200.0", "full_scales = [\n    0.0", "full_scales.*implausible"),
        ("pose_count = ", "pose_count = 1", r"tool\.pose_count is 1.* poses"),
        ("digest = ", "digest_ = ", r"unknown key.*file\.digest_|missing key file\.digest"),
    ],
)
def test_wrong_values_are_refused(tmp_path: Path, calibration, old: str, new: str,
                                  message: str) -> None:
    """Values that used to load silently are ConfigErrors naming the key."""
    path = tmp_path / "cal.toml"
    path.write_text(_edit(to_toml(calibration), old, new))
    with pytest.raises(ConfigError, match=message):
        load_calibration(path)


def test_a_file_cut_after_a_complete_pose_is_refused(tmp_path: Path, calibration) -> None:
    """Truncation at a table boundary leaves valid TOML; the pose count catches it."""
    text = to_toml(calibration)
    first = text.index("[[tool.pose]]")
    cut = text.index("[[tool.pose]]", first + 1)  # keep one whole pose, drop the rest
    path = tmp_path / "cal.toml"
    path.write_text(text[:cut])
    with pytest.raises(ConfigError, match=r"pose_count is \d+ but the file holds \d+ poses"):
        load_calibration(path)


def _digit_positions(text: str) -> list[int]:
    """Positions of digits in value lines (not comments, not the digest itself)."""
    positions, offset = [], 0
    for line in text.splitlines(keepends=True):
        if not line.startswith(("#", "digest")):
            positions += [offset + i for i, c in enumerate(line) if c.isdigit()]
        offset += len(line)
    return positions


def test_every_digit_flip_is_refused_or_harmless(tmp_path: Path, calibration) -> None:
    """Any digit changed in a value is refused (digest), never a different value."""
    text = to_toml(calibration)
    path = tmp_path / "cal.toml"
    positions = _digit_positions(text)
    assert len(positions) > 500
    for at in positions[::7]:
        flipped = text[:at] + str((int(text[at]) + 3) % 10) + text[at + 1 :]
        path.write_text(flipped)
        try:
            loaded = load_calibration(path)
        except ConfigError:
            continue
        assert loaded == calibration, f"a flip at {at} loaded a different calibration"


def test_astral_characters_are_written_so_that_they_read_back(tmp_path: Path,
                                                              calibration) -> None:
    """An emoji in a string was written as a surrogate pair tomllib refused."""
    from dataclasses import replace

    odd = replace(calibration, sensor=replace(calibration.sensor, model="JR3 😀 \U0010fffd"))
    path = tmp_path / "cal.toml"
    save_calibration(odd, path)
    assert load_calibration(path) == odd


def test_a_calibration_the_reader_would_refuse_is_not_written(tmp_path: Path,
                                                              calibration) -> None:
    """save_calibration checks its own output: node id 500 raises and no file appears."""
    from dataclasses import replace

    bad = replace(calibration, sensor=replace(calibration.sensor, node_id=500))
    with pytest.raises(ConfigError, match="node_id"):
        save_calibration(bad, tmp_path / "cal.toml")
    assert list(tmp_path.iterdir()) == []


def test_undecodable_bytes_and_directories_are_config_errors(tmp_path: Path,
                                                             calibration) -> None:
    """A non-UTF-8 byte and a directory named as the file were not ConfigErrors."""
    path = tmp_path / "cal.toml"
    data = bytearray(to_toml(calibration).encode())
    data[data.index(b"created") + 12] = 0xFF  # inside the created string
    path.write_bytes(bytes(data))
    with pytest.raises(ConfigError, match="not UTF-8"):
        load_calibration(path)
    with pytest.raises(ConfigError, match="is a directory"):
        load_calibration(tmp_path)
