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

This module runs them (:func:`run`, :func:`main`); each target's inputs and
checks live in its own module: ``link`` in :mod:`.link`, ``can`` in :mod:`.jr3`,
the file targets in :mod:`.files`, ``values`` and ``runs`` in :mod:`.configs`,
``egm``, ``netft-*`` and ``live-*`` in :mod:`.egm`, :mod:`.netft` and
:mod:`.live`; the mutations, :class:`FuzzFailure` and :class:`Tally` in
:mod:`.harness` (all re-exported here).

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
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import cast

from forcelearn.tools.fuzz.configs import (
    ODD_VALUES,
    RUN_TIMEOUT_S,
    check_run,
    emulated_example,
    loading_value_mutant,
    odd_value,
    value_mutant,
)
from forcelearn.tools.fuzz.files import (
    FileCase,
    calibration_case,
    calibration_values_case,
    check_file,
    config_case,
    file_mutations,
    filled_calibration,
    state_case,
    state_header_case,
)
from forcelearn.tools.fuzz.harness import (
    INTERESTING_BYTES,
    MUTATION_KINDS,
    FuzzFailure,
    Mutation,
    Tally,
    apply_mutations,
    random_mutations,
)
from forcelearn.tools.fuzz.jr3 import (
    FUZZ_FULL_SCALES,
    FUZZ_NODE,
    CanFrame,
    check_can,
    random_can_frames,
)
from forcelearn.tools.fuzz.link import check_link, link_stream, random_replies

__all__ = [
    "ALL_TARGETS", "EXTRA_TARGETS", "FUZZ_FULL_SCALES", "FUZZ_NODE", "INTERESTING_BYTES",
    "MUTATION_KINDS", "ODD_VALUES", "RUN_TIMEOUT_S", "TARGETS", "CanFrame", "FileCase",
    "FuzzFailure", "Mutation", "Tally", "apply_mutations", "calibration_case",
    "calibration_values_case", "check_can", "check_file", "check_link", "check_run",
    "config_case", "file_mutations", "filled_calibration", "link_stream", "loading_value_mutant",
    "main", "odd_value", "random_can_frames", "random_mutations", "random_replies", "run",
    "state_case", "state_header_case", "value_mutant",
]


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
                goods = [e.read_bytes() for e in examples if emulated_example(e)]
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
