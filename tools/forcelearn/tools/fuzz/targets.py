"""Mutation fuzzing of every decoder that takes bytes from outside the program.

Two properties, for each target (docs/fuzzing.md):

* **no foreign exception**: whatever the input, the decoder returns or raises
  an error of forcelearn's own tree (:class:`~forcelearn.errors.ForcelearnError`);
* **no accepted corruption**: what it accepts is exactly a value that was sent
  or saved, never a different one.

=============  ==============================================================
target         input and check
=============  ==============================================================
link           a stream of reply frames, mutated, fed in chunks to the
               FrameReader; every accepted payload must be one sent, and
               ``decode_reply`` raises only ProtocolError
can            CAN frames (valid ones mutated, and random ones) through the
               codec and the driver's listener; a decoded frame must encode
               back to the same bytes, every sample must equal a received
               force/moment pair scaled, and every frame is accounted for
state          a saved learner state file, mutated; ``load_learner`` gives
               StateFileError or the very learner that was saved; every other
               input has a member's .npy header damaged inside an intact
               archive (``fuzz_loaders``; first property only)
calibration    a calibration file, mutated; ``load_calibration`` gives
               ConfigError or the very calibration that was saved; every
               other input has odd values and a recomputed digest (first
               property only: the physical bounds must refuse)
config         the example cell configs, mutated; ``read_toml`` and
               ``load_cell_config`` give ConfigError or a value (configs carry
               no digest, so only the first property is checked)
values         the example cell configs, parsed, with one to three settings
               replaced by an odd value (another type, a table, NaN, inf,
               zero, a sign flip, a huge number); ``load_cell_config`` gives
               ConfigError or a value
egm            hostile datagrams and calls to the real EGM driver over
               loopback UDP (:mod:`forcelearn.tools.fuzz.egm`)
runs           ``values`` mutants that load, each run for 2 trials in its own
               process (``forcelearn run``, 180 s timeout): it ends, or stops
               with forcelearn's one-line message, never a traceback or a hang
               (not in the default targets: about 5 s an input)
=============  ==============================================================

The hypothesis tests in ``tests/tools/fuzz`` call the same ``check_*`` functions on
bounded inputs; the long run is::

    python -m forcelearn.tools.fuzz --inputs 100000 --seed 1
"""

from __future__ import annotations

import argparse
import functools
import importlib
import logging
import random
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import can
import numpy as np

from forcelearn.errors import ForcelearnError
from forcelearn.tools.fuzz.loaders import calibration_value_mutant, npz_header_mutant

if TYPE_CHECKING:
    from forcelearn.calibration import Calibration
    from forcelearn.devices import WrenchSample
    from forcelearn.learning import SRVLearner

Mutation = tuple[int, int, int]
"""(kind, position, value): kind 0 flip a bit, 1 set a byte, 2 insert, 3 delete, 4 truncate."""
MUTATION_KINDS = 5
INTERESTING_BYTES = (0x00, 0x10, 0x02, 0x03, 0xFF, 0x0A, 0x22, 0x5B, 0x30, 0x39)


class FuzzFailure(AssertionError):
    """A property failed: a foreign exception escaped, or a corruption was accepted."""


def apply_mutations(data: bytes, mutations: Iterable[Mutation]) -> bytes:
    """Return ``data`` with each mutation applied in turn (positions taken modulo the size)."""
    out = bytearray(data)
    for operation, position, value in mutations:
        size = len(out)
        at = position % (size + 1)
        if operation == 0 and size:
            out[at % size] ^= 1 << (value % 8)
        elif operation == 1 and size:
            out[at % size] = value & 0xFF
        elif operation == 2:
            out[at:at] = bytes((value & 0xFF,)) * (1 + (value >> 8) % 3)
        elif operation == 3 and size:
            del out[at : at + 1 + (value >> 8) % 3]
        elif operation == 4:
            del out[at:]
    return bytes(out)


def random_mutations(rng: random.Random, max_count: int = 4) -> list[Mutation]:
    """Draw 1..max_count mutations, biased towards the protocol's special bytes."""
    mutations = []
    for _ in range(rng.randint(1, max_count)):
        operation = rng.choices(range(MUTATION_KINDS), weights=(4, 3, 3, 2, 1))[0]
        byte = rng.choice(INTERESTING_BYTES) if rng.random() < 0.5 else rng.randrange(256)
        mutations.append((operation, rng.randrange(1 << 20), byte | rng.randrange(4) << 8))
    return mutations


def _foreign(exc: BaseException, what: str) -> FuzzFailure:
    return FuzzFailure(f"{what} raised {type(exc).__name__}: {exc}")


# ---- link -----------------------------------------------------------------------------
def link_stream(payloads: Sequence[bytes]) -> bytes:
    """The wire bytes of ``payloads`` sent one after another."""
    from forcelearn.protocols.computer_link import framing

    return b"".join(framing.encode(p) for p in payloads)


def check_link(sent: Sequence[bytes], received: bytes, chunk: int = 7) -> str:
    """Feed ``received`` to a FrameReader; "accepted" if every sent frame came through."""
    from forcelearn.protocols.computer_link import framing
    from forcelearn.protocols.computer_link import messages as m

    reader = framing.FrameReader()
    accepted: list[bytes] = []
    try:
        for i in range(0, len(received), chunk):
            for frame in reader.feed(received[i : i + chunk]):
                if isinstance(frame, framing.DataFrame):
                    accepted.append(frame.payload)
    except Exception as exc:
        raise _foreign(exc, "FrameReader.feed") from exc
    extra = Counter(accepted) - Counter(sent)
    if extra:
        raise FuzzFailure(f"accepted payload(s) never sent: {list(extra)!r}")
    for payload in accepted:
        try:
            m.decode_reply(payload)
        except ForcelearnError:
            pass
        except Exception as exc:
            raise _foreign(exc, "decode_reply") from exc
    return "accepted" if Counter(accepted) == Counter(sent) else "rejected"


def random_replies(rng: random.Random) -> list[bytes]:
    """One to three reply payloads of the kinds the controller sends."""
    from forcelearn.protocols.computer_link import messages as m

    payloads = []
    for _ in range(rng.randint(1, 3)):
        command = rng.choice(list(m.Command))
        tns = rng.randrange(0x10000)
        if rng.random() < 0.2:
            reply = m.Reply(command, tns, int(m.ErrorCode.OUT_OF_WORKSPACE), reason="refused")
        elif command is m.Command.READ_POSITION:
            values = [rng.uniform(-2000, 2000) for _ in range(13)]
            body = m.position_body(m.Position(values[:3], values[3:7], values[7:]))  # type: ignore[arg-type]
            reply = m.Reply(command, tns, m.ErrorCode.OK, body=body)
        else:
            reply = m.Reply(command, tns, m.ErrorCode.OK)
        payloads.append(m.encode_reply(reply))
    return payloads


# ---- CAN ------------------------------------------------------------------------------
FUZZ_NODE = 1
FUZZ_FULL_SCALES = np.array([200.0, 200.0, 400.0, 20.0, 20.0, 20.0])


@dataclass
class CanFrame:
    """One frame as python-can would deliver it."""

    arbitration_id: int
    data: bytes
    is_extended_id: bool = False
    is_remote_frame: bool = False
    is_error_frame: bool = False

    def message(self) -> can.Message:
        """The python-can message (data cut to the 8 bytes CAN carries)."""
        return can.Message(arbitration_id=self.arbitration_id, data=self.data[:8],
                           is_extended_id=self.is_extended_id,
                           is_remote_frame=self.is_remote_frame,
                           is_error_frame=self.is_error_frame, check=False)


def check_can(frames: Sequence[CanFrame]) -> str:
    """Codec round trip, listener never raising, samples equal to received pairs."""
    from forcelearn.drivers.jr3_can.listener import Jr3Listener
    from forcelearn.protocols.jr3_can import codec
    from forcelearn.protocols.jr3_can.opcodes import JR3_MBED_2023_12

    listener = Jr3Listener(FUZZ_NODE, JR3_MBED_2023_12, 26214)
    listener.set_full_scales(FUZZ_FULL_SCALES)
    samples: list[WrenchSample] = []
    listener.callbacks.append(samples.append)
    forces: dict[int, list[tuple[int, ...]]] = {}
    moments: dict[int, list[tuple[int, ...]]] = {}
    decoded_any = False
    for frame in frames:
        msg = frame.message()
        try:
            result = codec.decode(msg.arbitration_id, msg.data, is_extended_id=msg.is_extended_id,
                                  opcodes=JR3_MBED_2023_12)
        except Exception as exc:
            raise _foreign(exc, "codec.decode") from exc
        if isinstance(result, codec.Decoded):
            decoded_any = True
            again = codec.encode(result.message, result.node_id or 1, JR3_MBED_2023_12)
            if (again.arbitration_id, again.data) != (msg.arbitration_id, bytes(msg.data)):
                raise FuzzFailure(f"{msg} decoded to {result}, which encodes to {again}")
            accepted = not (msg.is_remote_frame or msg.is_error_frame)
            if accepted and result.node_id == FUZZ_NODE:
                if isinstance(result.message, codec.Forces):
                    forces.setdefault(result.message.counter, []).append(result.message.raw)
                elif isinstance(result.message, codec.Moments):
                    moments.setdefault(result.message.counter, []).append(result.message.raw)
        try:
            listener.on_message_received(msg)
        except Exception as exc:
            raise _foreign(exc, "Jr3Listener.on_message_received") from exc
    scale = FUZZ_FULL_SCALES / 16384
    for sample in samples:
        raw = np.rint(sample.wrench / scale).astype(int)
        f, mo = tuple(raw[:3].tolist()), tuple(raw[3:].tolist())
        if f not in forces.get(sample.counter, ()) or mo not in moments.get(sample.counter, ()):
            raise FuzzFailure(f"sample {sample} matches no received pair")
    stats = listener.stats()
    axes_frames = sum(len(v) for v in forces.values()) + sum(len(v) for v in moments.values())
    paired = stats.samples + stats.samples_before_full_scales + stats.duplicate_samples
    if stats.frames != len(frames):
        raise FuzzFailure(f"listener counted {stats.frames} frames of {len(frames)}")
    if axes_frames != 2 * paired + stats.unpaired_frames + stats.pending_frames:
        raise FuzzFailure(f"{axes_frames} force/moment frames but {stats} account for others")
    return "accepted" if decoded_any else "rejected"


def random_can_frames(rng: random.Random) -> list[CanFrame]:
    """A short burst: valid frames of the node (some mutated) and random frames."""
    from forcelearn.protocols.jr3_can import codec
    from forcelearn.protocols.jr3_can.opcodes import JR3_MBED_2023_12

    frames = []
    counter = rng.randrange(0x10000)
    for _ in range(rng.randint(1, 12)):
        roll = rng.random()
        if roll < 0.6:
            raw = tuple(rng.randint(-32768, 32767) for _ in range(3))
            kind = codec.Forces if rng.random() < 0.5 else codec.Moments
            counter = (counter + rng.choice((0, 0, 1, 2))) % 0x10000
            message: codec.Message = kind(raw, counter)  # type: ignore[arg-type]
            if rng.random() < 0.1:
                message = codec.Ack(rng.randrange(2), (rng.randrange(0x10000),) * 3)
            wire = codec.encode(message, FUZZ_NODE, JR3_MBED_2023_12)
            data = wire.data
            if rng.random() < 0.3:
                data = apply_mutations(data, random_mutations(rng, 2))
            frames.append(CanFrame(wire.arbitration_id, data))
        else:
            frames.append(CanFrame(
                rng.randrange(1 << (29 if roll > 0.95 else 11)),
                rng.randbytes(rng.randint(0, 8)),
                is_extended_id=roll > 0.95,
                is_remote_frame=rng.random() < 0.05,
                is_error_frame=rng.random() < 0.05,
            ))
    return frames


# ---- files ----------------------------------------------------------------------------
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
        raise _foreign(exc, f"loading a damaged {case.path.name}") from exc
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


def _emulated(example: Path) -> bool:
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


def file_mutations(rng: random.Random, case: FileCase) -> list[Mutation]:
    """Mutations for a file: for text files, digit changes are frequent."""
    mutations = random_mutations(rng, 3)
    if case.path.suffix == ".toml" and rng.random() < 0.5:
        digits = [i for i, b in enumerate(case.good) if 0x30 <= b <= 0x39]
        at = rng.choice(digits)
        mutations = [(1, at, 0x30 + rng.randrange(10))]
    return mutations


# ---- the long run ---------------------------------------------------------------------
@dataclass
class Tally:
    """Outcome of one target's run."""

    inputs: int = 0
    outcomes: Counter[str] = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)

    def add(self, run: Callable[[], str]) -> None:
        """Run one input and count its outcome (a FuzzFailure is recorded, not raised)."""
        self.inputs += 1
        try:
            self.outcomes[run()] += 1
        except FuzzFailure as exc:
            kind = "accepted corruption" if "raised" not in str(exc) else "foreign exception"
            self.outcomes[kind] += 1
            if len(self.failures) < 10:
                self.failures.append(str(exc))


def run(
    targets: Sequence[str], inputs: int, seed: int, examples: Sequence[Path]
) -> dict[str, Tally]:
    """Run ``inputs`` mutated inputs per target; returns a Tally per target."""
    rng = random.Random(seed)
    tallies: dict[str, Tally] = {}
    with tempfile.TemporaryDirectory(prefix="forcelearn-fuzz-") as tmp:
        folder = Path(tmp)
        for target in targets:
            tally = tallies[target] = Tally()
            started = time.monotonic()
            if target == "link":
                for _ in range(inputs):
                    sent = random_replies(rng)
                    data = apply_mutations(link_stream(sent), random_mutations(rng))
                    # add() runs it at once: the chunk size is drawn right after the mutations.
                    tally.add(functools.partial(check_link, sent, data, rng.randint(1, 17)))
            elif target == "can":
                for _ in range(inputs):
                    frames = random_can_frames(rng)
                    tally.add(functools.partial(check_can, frames))
            elif target == "values":
                value_cases = [config_case(folder, e) for e in examples]
                for i in range(inputs):
                    case = value_cases[i % len(value_cases)]
                    tally.add(functools.partial(check_file, case, value_mutant(rng, case.good)))
            elif target == "egm":
                from forcelearn.tools.fuzz import egm as fuzz_egm

                egm = fuzz_egm.run_target(
                    inputs, rng, lambda data, r: apply_mutations(data, random_mutations(r)))
                unsafe = egm.outcomes.pop("unsafe", 0)  # hostile input obeyed: counted as
                if unsafe:                               # an accepted corruption
                    egm.outcomes["accepted corruption"] = unsafe
                tally.inputs, tally.outcomes, tally.failures = inputs, egm.outcomes, egm.failures
                print(f"{target:12s} driver counters {dict(egm.counters)}", flush=True)
            elif target in EXTRA_TARGETS:  # the socket targets, in their own modules
                importlib.import_module(EXTRA_TARGETS[target]).run_target(
                    target, rng, inputs, tally)
            elif target == "runs":
                goods = [e.read_bytes() for e in examples if _emulated(e)]
                for i in range(inputs):
                    config, changes = loading_value_mutant(rng, goods[i % len(goods)], folder)
                    tally.add(functools.partial(check_run, config, folder / "run", changes))
            else:
                cases = {"state": lambda: [state_case(folder), state_header_case(folder)],
                         "calibration": lambda: [calibration_case(folder),
                                                 calibration_values_case(folder)],
                         "config": lambda: [config_case(folder, e) for e in examples]}[target]()
                for i in range(inputs):
                    case = cases[i % len(cases)]
                    mutant = cast("Callable[[random.Random, bytes], bytes] | None",
                                  case.extra.get("mutant"))
                    if mutant is not None:
                        data = mutant(rng, case.good)
                    else:
                        data = apply_mutations(case.good, file_mutations(rng, case))
                    tally.add(functools.partial(check_file, case, data))
            elapsed = time.monotonic() - started
            print(f"{target:12s} {tally.inputs:8d} inputs  {elapsed:7.1f} s  "
                  f"{dict(sorted(tally.outcomes.items()))}", flush=True)
            for failure in tally.failures:
                print(f"    {failure}", flush=True)
    return tallies


EXTRA_TARGETS = {
    **dict.fromkeys(("netft-xml", "netft-http", "netft-tcp", "netft-rdt"),
                    "forcelearn.tools.fuzz.netft"),
    **dict.fromkeys(("live-http", "live-slow"), "forcelearn.tools.fuzz.live"),
}
"""Targets run by another module's ``run_target(target, rng, inputs, tally)`` (imported by
name when run: they import this module's helpers): netft-* (``fuzz_netft``: the Net F/T's
XML, HTTP, READCALINFO and RDT over loopback, lying and dripping servers included) and
live-* (``fuzz_live``: the live server's HTTP and slow clients); docs/fuzzing.md."""
TARGETS = ("link", "can", "state", "calibration", "config", "values", "egm", *EXTRA_TARGETS)
"""The default targets; ``runs`` is named on its own (it runs the cell)."""
ALL_TARGETS = (*TARGETS, "runs")


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m forcelearn.tools.fuzz [--inputs N] [--seed S] [TARGET...]``."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.fuzz",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("targets", nargs="*", help=f"any of {', '.join(ALL_TARGETS)} "
                        f"(default: all but runs)")
    parser.add_argument("--inputs", type=int, default=100_000, help="inputs per target")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--examples", type=Path, nargs="*",
                        default=sorted(Path("examples").glob("*.toml")),
                        help="cell configs to mutate (config, values and runs targets)")
    args = parser.parse_args(argv)
    logging.getLogger("forcelearn").setLevel(logging.CRITICAL)  # damaged input is expected here
    unknown = sorted(set(args.targets) - set(ALL_TARGETS))
    if unknown:
        parser.error(f"unknown target(s) {unknown}; known: {', '.join(ALL_TARGETS)}")
    tallies = run(args.targets or TARGETS, args.inputs, args.seed, args.examples)
    bad = sum(t.outcomes["foreign exception"] + t.outcomes["accepted corruption"]
              for t in tallies.values())
    print(f"total: {bad} foreign exceptions or accepted corruptions")
    return 1 if bad else 0


if __name__ == "__main__":
    # The module's own copy, not __main__'s: the socket targets' modules import it, and a
    # FuzzFailure they raise must be the class Tally.add catches.
    from forcelearn.tools.fuzz.targets import main as _main

    sys.exit(_main())
