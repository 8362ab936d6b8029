"""Learner state files: bit-exact round trip, atomic writes, clear errors."""

import json
from pathlib import Path

import numpy as np
import pytest

from forcelearn.errors import StateFileError
from forcelearn.learning import (
    BoxGrid,
    Dimension,
    SRVLearner,
    SRVParams,
    load_learner,
    save_learner,
    state_file,
)


def trained_learner(seed: int = 3) -> SRVLearner:
    """A learner with some history: non-trivial W, V, phase count and RNG state."""
    grid = BoxGrid([Dimension("t1", 30, 60, 30), Dimension("t2", -75, -15, 40)])
    learner = SRVLearner(grid, 2, SRVParams(success_trials=3), rng=seed)
    run_steps(learner, 200, seed)
    learner.end_trial(True)
    learner.end_trial(False)
    learner.end_trial(True)
    return learner


def run_steps(learner: SRVLearner, n: int, seed: int) -> list[np.ndarray]:
    """Drive the learner over a fixed input sequence; return the actions drawn."""
    xs = np.random.default_rng(seed + 100).uniform([30, -75], [60, -15], size=(n, 2))
    actions = []
    for x in xs:
        step = learner.act(x)
        actions.append(step.action)
        learner.learn(step, float(np.clip(np.abs(step.action).sum() / 3, 0, 2)))
    return actions


def test_round_trip_is_bit_exact_and_continues_the_random_sequence(tmp_path: Path) -> None:
    """A loaded learner equals the saved one and draws exactly what it would have drawn."""
    learner = trained_learner()
    path = tmp_path / "learner.npz"
    save_learner(learner, path, metadata={"run": "abc", "trial": 3})
    loaded, metadata = load_learner(path)
    assert metadata == {"run": "abc", "trial": 3}
    assert np.array_equal(loaded.weights, learner.weights)
    assert np.array_equal(loaded.predictions, learner.predictions)
    assert loaded.params == learner.params
    assert loaded.schedule == learner.schedule
    assert loaded.grid.shape == learner.grid.shape
    continued = run_steps(learner, 100, 9)
    resumed = run_steps(loaded, 100, 9)
    assert all(np.array_equal(a, b) for a, b in zip(continued, resumed, strict=True))
    assert np.array_equal(loaded.weights, learner.weights)


def test_file_is_readable_without_pickle(tmp_path: Path) -> None:
    """Every array loads with allow_pickle=False (no object arrays)."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    with np.load(path, allow_pickle=False) as archive:
        assert {a.dtype.kind for a in (archive[k] for k in archive.files)} <= set("fiUb")
        assert int(archive["format_version"]) == state_file.FORMAT_VERSION


def test_failed_write_leaves_the_old_file_and_no_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A crash while writing keeps the previous state intact (temp file + rename)."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    before = path.read_bytes()

    def explode(*args: object, **kwargs: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", explode)
    with pytest.raises(OSError, match="disk full"):
        save_learner(trained_learner(seed=4), path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["learner.npz"]


def test_truncated_file_fails_with_a_clear_message(tmp_path: Path) -> None:
    """A half-written file is a StateFileError that says what to do."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(StateFileError, match="restore it from a backup"):
        load_learner(path)


def test_other_format_version_is_refused(tmp_path: Path) -> None:
    """A file of another version names both versions."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["format_version"] = np.array(99)
    np.savez(path, **arrays)
    with pytest.raises(StateFileError, match="version 99"):
        load_learner(path)


def test_missing_key_and_foreign_files_are_refused(tmp_path: Path) -> None:
    """A damaged archive, another .npz and a missing file all raise StateFileError."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files if k != "predictions"}
    np.savez(path, **arrays)
    with pytest.raises(StateFileError, match="damaged"):
        load_learner(path)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(StateFileError, match="not a forcelearn learner state"):
        load_learner(other)
    with pytest.raises(StateFileError, match="no learner state"):
        load_learner(tmp_path / "absent.npz")
    text = tmp_path / "text.npz"
    text.write_text("hello")
    with pytest.raises(StateFileError):
        load_learner(text)


def test_inconsistent_shapes_are_refused(tmp_path: Path) -> None:
    """Weights that do not fit the saved grid are caught at load."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["weights"] = arrays["weights"][:-1]
    np.savez(path, **arrays)
    with pytest.raises(StateFileError, match="do not fit the grid"):
        load_learner(path)
    assert json.loads(str(arrays["params_json"]))["success_trials"] == 3


def test_extra_arrays_are_saved_beside_the_learner(tmp_path: Path) -> None:
    """Caller arrays round-trip exactly and never collide with the learner's keys."""
    from forcelearn.learning import load_extra_arrays

    path = tmp_path / "learner.npz"
    history = np.random.default_rng(0).normal(size=(7, 20))
    save_learner(trained_learner(), path, arrays={"history": history, "weights": np.arange(3)})
    extras = load_extra_arrays(path)
    assert np.array_equal(extras["history"], history)
    assert extras["weights"].tolist() == [0, 1, 2]
    learner, _ = load_learner(path)
    assert np.array_equal(learner.weights, trained_learner().weights)


def _saved_arrays(tmp_path: Path) -> dict[str, np.ndarray]:
    path = tmp_path / "good.npz"
    save_learner(trained_learner(), path)
    with np.load(path) as archive:
        return {k: archive[k] for k in archive.files}


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("weights", "nan", "NaN"),
        ("predictions", "inf", "NaN or infinite"),
        ("trials", np.array(-1), "trials"),
        ("trials", np.array(10**12), "trials"),
        ("trials", np.array(2.7), "trials"),
        ("consecutive_successes", np.array(10**6), "consecutive_successes"),
        ("switch_trial", np.array(-5), "switch_trial"),
        ("phase", np.array(7), "phase"),
        ("metadata_json", np.array("[1, 2]"), "metadata_json"),
        ("rng_json", np.array('{"bit_generator": "seed"}'), "bit generator 'seed'"),
        ("grid_parts", np.array([10**5, 10**5]), "grid_parts"),
    ],
)
def test_nonsense_values_are_refused(
    tmp_path: Path, key: str, value: object, match: str
) -> None:
    """Each nonsense value is a StateFileError naming the key, never a silent load.

    NaN weights, counters out of range or not integers, a list as metadata, a
    foreign rng name (which used to be *called*, re-seeding the global RNG).
    """
    arrays = _saved_arrays(tmp_path)
    if isinstance(value, str):  # poison one element of a float array
        arrays[key] = arrays[key].copy()
        arrays[key].flat[3] = float(value)
    else:
        arrays[key] = value  # type: ignore[assignment]
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    before = np.random.get_state()[1].copy()
    with pytest.raises(StateFileError, match=match):
        load_learner(path)
    assert np.array_equal(np.random.get_state()[1], before), "the global RNG was touched"


def test_damaged_zip_compression_field_is_a_state_file_error(tmp_path: Path) -> None:
    """An unknown compression method in the zip headers raised NotImplementedError."""
    path = tmp_path / "learner.npz"
    save_learner(trained_learner(), path)
    data = bytearray(path.read_bytes())
    at = data.find(b"PK\x01\x02")  # first central directory entry; method at offset 10
    data[at + 10 : at + 12] = (99).to_bytes(2, "little")
    path.write_bytes(bytes(data))
    with pytest.raises(StateFileError, match="restore it from a backup"):
        load_learner(path)


def test_plain_npy_and_garbage_are_refused_without_pickle_advice(tmp_path: Path) -> None:
    """A .npy under the name (was TypeError) and garbage both say what the file is not.

    Neither passes on numpy's advice to load the file with pickle.
    """
    npy = tmp_path / "array.npz"
    with open(npy, "wb") as handle:
        np.save(handle, np.zeros(3))
    with pytest.raises(StateFileError, match=r"single \.npy array"):
        load_learner(npy)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"\x80\x04garbage that looks like a pickle")
    with pytest.raises(StateFileError) as caught:
        load_learner(garbage)
    assert "pickle" not in str(caught.value)
    with pytest.raises(StateFileError, match=r"single \.npy array"):
        state_file.load_extra_arrays(npy)
