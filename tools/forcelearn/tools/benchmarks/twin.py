"""Benchmark: the twin's fit wall time (``forcelearn twin``'s fit, without the report).

By default it first makes the records of a ``--trials`` run in process (the
emulator's sponge, arm and JR3 sensor model, noise 0.2 N; not timed), with the
surface probe's records first as a run directory has them (the seven points the
default run probes), then times the fit: every family member, the arm and the sensor, the held-out
scoring. ``--run-dir`` times the fit on a real run directory's records instead, as ``forcelearn
twin`` fits them (the run's config, the link's polling).
CPU and wall time are printed; the wall time depends on the host's load.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.records import TrialRecords
from forcelearn.site.config import load_cell_config
from forcelearn.tools.twin.fit import fit_twin
from forcelearn.tools.twin.setup import base_arm, base_sponge, configured_colour, reading_of
from forcelearn.tools.twin.simulate import SimulatedRun, simulate_run

PROBE_POINTS = (0.0, 0.5, 1.0, 0.125, 0.375, 0.625, 0.875)
"""Where the default run's probe presses, in its order (its three points, then the four it
adds between them: docs/surface.md)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench twin``."""
    parser.add_argument("--trials", type=int, default=300,
                        help="trials of the simulated run (default 300)")
    parser.add_argument("--burst-samples", type=int, default=25,
                        help="samples per burst of the simulated run (default 25)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the simulated run")
    parser.add_argument("--run-dir", type=Path, default=None,
                        help="time the fit on this run directory's records instead")


def _records(args: argparse.Namespace) -> list[TrialRecords]:
    sensor = Jr3ModelParams(noise_std=(0.2,) * 3 + (0.02,) * 3, initial_bias=(0.0,) * 6,
                            bias_drift_per_sqrt_s=(0.0,) * 6)
    run = SimulatedRun(trials=args.trials, sensor=sensor, burst_samples=args.burst_samples,
                       probe_points=PROBE_POINTS)
    return simulate_run(run, seed=args.seed)


def run(args: argparse.Namespace) -> int:
    """Make or read the records, then time one fit."""
    made = time.perf_counter()
    polling = None
    if args.run_dir is not None:  # as forcelearn twin fits it: the run's config and polling
        from forcelearn.emulators.physics.arm import ArmConfig
        from forcelearn.tools.twin.arm import polling_of
        from forcelearn.tools.twin.source import read_runs

        source = read_runs([args.run_dir])
        records, config = source.records, source.config
        polling = polling_of(config.robot, ArmConfig())
    else:
        records, config = _records(args), load_cell_config(None)
    moves = sum(len(t.steps) for t in records)
    print(f"records: {len(records)} trials, {moves} moves "
          f"({time.perf_counter() - made:.1f} s to make or read, not timed)")
    wall, cpu = time.perf_counter(), time.process_time()
    fit = fit_twin(records, base_sponge(config), base_arm(), reading_of(config),
                   config.emulator.arm.in_position_mm, config.emulator.arm.tick_s,
                   configured_phi=configured_colour(config, records), polling=polling)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(f"fit: wall {wall:.1f} s, CPU {cpu:.1f} s; member {fit.chosen.member.name}, "
          f"held-out RMS {fit.chosen.heldout_rms_n:.3f} N over {fit.heldout.trials} trials")
    return 0
