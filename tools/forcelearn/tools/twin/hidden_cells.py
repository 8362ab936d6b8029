"""Hidden cells: emulated cells drawn over stated ranges, the truth a twin is checked against.

The twin is checked on cells nobody hand-set: each is drawn from a seed,
written as a cell config that ``forcelearn run --config FILE`` runs as it is,
with a JSON of every drawn parameter (the hidden truth) beside it::

    python -m forcelearn.tools.twin.hidden_cells --count 30 --seed 1 --out DIR
    # DIR/cell-01.toml, DIR/cell-01.truth.json, ..., DIR/hidden-cells.json

Cell ``i`` of a seed is drawn from its own generator (``seed``, ``i``), so it is
the same whatever ``--count`` is.

Ranges (:class:`HiddenCellRanges`; log: log-uniform, else uniform)
-------------------------------------------------------------------
=========================  ==================  =====================================
drawn                      range               goes to
=========================  ==================  =====================================
stiffness k                0.5-8 N/mm (log)    ``[emulator.sponge] stiffness_n_per_mm``
desired force              0.5-3 kgf           ``[task] desired_force_n`` (N)
wear rate                  0.3-5 x today (log) ``softening_passes``, ``set_passes`` divided by it
wear amplitude             0.5-1.5 x today     ``softening`` (0.30), ``set_mm`` (2 mm) times it
relaxation ratio           0-1                 ``relaxation_ratio``
relaxation time            0.2-1 s             ``relaxation_time_s``
contact position           -3..3 mm            ``surface_y_mm`` (surface Y at the strip's top)
arm lag                    0.01-0.2 s (log)    ``[emulator.arm] lag_s``
arm acceleration           300-3000 mm/s^2     ``[emulator.arm] accel_mm_s2`` (drawn from its own
                           (log)               stream: the other draws are those of before)
sensor noise               0.05-1 N (log)      ``[emulator.sensor] noise_std`` (forces; moments
                                               a tenth of it in N*m, as today's 0.2 / 0.02)
nonlinear foam (1 in 2)    n = 1.1-1.6         ``stiffening_exponent`` (else 1: linear)
hysteresis (1 in 3)        h = 0.05-0.3        ``hysteresis_loss`` (else 0; docs/materials.md)
friction (1 in 3)          mu = 0.05-0.4       ``friction_coefficient`` (else 0)
periodic shapes            waviness 0.3-2 mm   ``waviness_mm``, ``waviness_wavelength_mm``,
(``--shaped``, share;      over 50-160 mm,     ``stiffness_variation``,
default none)              stiffness variation ``stiffness_wavelength_mm`` (else the
                           0-0.3 over 60-240   defaults, 1 mm over 80 mm and 0.15 over
                           mm                  120 mm; drawn from their own stream)
=========================  ==================  =====================================

Every other sponge, arm and sensor parameter keeps its default. The twin starts its fit
from the defaults, so a study without ``--shaped`` cells starts every cell's periodic
shapes at their truth: ``--shaped`` checks what a site's own strip would.

Settings derived so that every drawn cell is runnable (as a site would set them)
-------------------------------------------------------------------------------
* Foam thickness: at least 40 mm (today's), and 1.4 x the depth the desired
  force needs on the most worn, softest part of the foam (stiffness ``k (1 -
  variation) (1 - softening)``, on the unloading branch, plus the final set)
  + 5 mm, rounded up to 5 mm: a soft foam at a large force is a thick foam.
  The probe's ``max_depth_mm`` is 95 % of it, as today (38 of 40 mm).
* ``[safety] max_force_n`` = 3 x the desired force (today's 60 N for 2 kgf,
  rounded down); the workspace's Y reaches 10 mm below the foam's backing and
  10 mm above the retract plane (never inside today's -60..60 mm).
* ``[task] start_mm``: Y where the fresh, relaxed foam pushes half the desired
  force at the start Z (today's start presses about 0.6 of it); ``retract_y_mm``
  10 mm above the highest surface point of the path (today's 15 mm), and
  above the fallback output range (start Y + 15 mm) that the task checks.
* ``[probe] dwell_s`` = max(1.5 s, 4 relaxation times): the probe reads a
  relaxed force, as its docstring asks.
* ``[probe] samples`` = 16 x (noise / 0.2 N)^2, 16..400, and ``contact_force_n`` =
  max(1 N, 3 x noise): a noisy sensor averages as long as today's 0.2 N one
  for the probe's readings, and noise never marks contact. With today's 16
  samples and 1 N, a 0.71 N sensor read 1.1 N in free space and the probe
  stopped ("already in contact"; hidden cell 02 of seed 1).
* ``[filter] measurement_variance_n2`` = noise std squared: what
  ``forcelearn calibrate`` measures on site and the operator copies there.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge_law import (
    SpongeParams,
    depth_for_force_mm,
    stiffness_n_per_mm,
    surface_y_mm,
)
from forcelearn.site.config import SafetyLimits, load_cell_config
from forcelearn.tasks.surface import KGF_N, SurfaceTaskSpec
from forcelearn.tools.twin.wavelength_search import SHAPES

Range = tuple[float, float]

MODULE = "forcelearn.tools.twin.hidden_cells"
"""This generator's import path (written into every file it makes)."""

MIN_THICKNESS_MM = 40.0
"""Thinnest foam a hidden cell gets (today's), mm."""
THICKNESS_MARGIN = 1.4
"""Foam thickness over the depth the desired force needs on the worn, soft foam."""
FORCE_LIMIT_RATIO = 3.0
"""``safety.max_force_n`` over the desired force (today's 60 N over 19.6 N)."""
START_FORCE_RATIO = 0.5
"""The start press's force (fresh, relaxed foam) over the desired force."""
PROBE_DEPTH_SHARE = 0.95
"""``probe.max_depth_mm`` over the foam thickness (today's 38 of 40 mm)."""
CLEARANCE_MM = 10.0
"""Retract plane above the highest surface point; workspace beyond backing and retract, mm."""
TODAY_NOISE_N = 0.2
"""The default emulated sensor's force noise std, N."""
PROBE_SAMPLES = 16
"""The probe's samples per reading at today's noise."""
MAX_PROBE_SAMPLES = 400
"""Most samples per probe reading a hidden cell gets (0.4 s of the 1 kHz sensor)."""
CONTACT_NOISE_RATIO = 3.0
"""The probe's contact threshold over the noise std (never under today's 1 N)."""


@dataclass(frozen=True)
class HiddenCellRanges:
    """The ranges cells are drawn from (a plausible site's spread, and the contact position)."""

    stiffness_n_per_mm: Range = (0.5, 8.0)
    desired_force_kgf: Range = (0.5, 3.0)
    wear_rate: Range = (0.3, 5.0)
    wear_amplitude: Range = (0.5, 1.5)
    relaxation_ratio: Range = (0.0, 1.0)
    relaxation_time_s: Range = (0.2, 1.0)
    surface_y_mm: Range = (-3.0, 3.0)
    lag_s: Range = (0.01, 0.2)
    accel_mm_s2: Range = (300.0, 3000.0)
    """The arm's path acceleration (the emulator's default 1000 mm/s^2 inside): studies
    generated before session 13 drew none and ran every cell at 1000, where a fit that never
    moved its acceleration from the default would have been right."""
    noise_n: Range = (0.05, 1.0)
    stiffening_exponent: Range = (1.1, 1.6)
    hysteresis_loss: Range = (0.05, 0.3)
    """Flexible PU foams lose 20-46 % of a compression cycle's work, h = L / (2 - L)
    (docs/materials.md)."""
    friction_coefficient: Range = (0.05, 0.4)
    waviness_mm: Range = (0.3, 2.0)
    waviness_wavelength_mm: Range = (50.0, 160.0)
    stiffness_variation: Range = (0.0, 0.3)
    stiffness_wavelength_mm: Range = (60.0, 240.0)
    nonlinear_share: float = 0.5
    """Share of the cells whose foam stiffens (the rest are linear)."""
    hysteresis_share: float = 1 / 3
    friction_share: float = 1 / 3
    shaped_share: float = 0.0
    """Share of the cells whose strip has periodic shapes of its own (the rest keep the
    defaults, where the twin's fit starts). Studies before session 18 drew none."""

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if name.endswith("_share"):
                if not 0.0 <= value <= 1.0:
                    raise ValueError(f"hidden-cell range {name} = {value!r}: a share in [0, 1]")
                continue
            low, high = value
            if not (math.isfinite(low) and math.isfinite(high) and low <= high):
                raise ValueError(f"hidden-cell range {name} = {value!r}: need low <= high")
        for name in ("stiffness_n_per_mm", "wear_rate", "lag_s", "accel_mm_s2", "noise_n"):
            if getattr(self, name)[0] <= 0:
                raise ValueError(f"hidden-cell range {name}: drawn log-uniform, so it must be > 0")


@dataclass(frozen=True)
class HiddenCell:
    """One drawn cell: its physics (the hidden truth) and the settings derived from it."""

    name: str
    sponge: SpongeParams
    lag_s: float
    """Servo lag of the arm, s."""
    noise_n: float
    """Sensor noise std of the forces at the adapter's output, N."""
    desired_force_n: float
    wear_rate: float
    """Wear rate over today's (softening_passes and set_passes divided by it)."""
    wear_amplitude: float
    """Softening and set over today's."""
    derived: dict[str, float] = field(default_factory=dict)
    """Settings that make the cell runnable (see the module), mm, N, s."""
    accel_mm_s2: float = ArmConfig().accel_mm_s2
    """The arm's path acceleration, mm/s^2."""


def _tidy(value: float) -> float:
    """A drawn value to 6 significant digits (the files are read by people)."""
    return float(f"{value:.6g}")


def _uniform(rng: np.random.Generator, bounds: Range) -> float:
    return _tidy(float(rng.uniform(bounds[0], bounds[1])))


def _log_uniform(rng: np.random.Generator, bounds: Range) -> float:
    return _tidy(math.exp(float(rng.uniform(math.log(bounds[0]), math.log(bounds[1])))))


def _path_z_mm(task: SurfaceTaskSpec) -> np.ndarray:
    z0 = task.start_mm[2]
    return np.asarray(z0 + task.z_step_mm * np.arange(task.steps_per_trial + 1))


def _derive(sponge: SpongeParams, desired_force_n: float) -> tuple[SpongeParams, dict[str, float]]:
    """The foam thickness and the settings that make a drawn cell runnable (module docstring)."""
    worn = (sponge.stiffness_n_per_mm * (1 - sponge.stiffness_variation)
            * (1 - sponge.softening) * (1 - sponge.hysteresis_loss))
    needed = depth_for_force_mm(sponge, desired_force_n, worn) + sponge.set_mm
    thickness = max(MIN_THICKNESS_MM, 5.0 * math.ceil((THICKNESS_MARGIN * needed + 5.0) / 5.0))
    sponge = replace(sponge, thickness_mm=thickness)

    task = SurfaceTaskSpec()
    x0, _, z0 = task.start_mm
    path = [surface_y_mm(sponge, 0, float(z)) for z in _path_z_mm(task)]
    start_depth = depth_for_force_mm(
        sponge, START_FORCE_RATIO * desired_force_n, stiffness_n_per_mm(sponge, 0, z0)
    )
    start_y = round(surface_y_mm(sponge, 0, z0) - start_depth, 1)
    retract_y = float(math.ceil(max(max(path) + CLEARANCE_MM, start_y + task.fallback_offset_mm
                                    + 1.0)))
    limits = SafetyLimits()
    low_y = min(limits.workspace_min_mm[1],
                math.floor(min(path) - sponge.set_mm - thickness - CLEARANCE_MM))
    high_y = max(limits.workspace_max_mm[1], retract_y + CLEARANCE_MM)
    return sponge, {
        "thickness_mm": thickness,
        "max_force_n": _tidy(FORCE_LIMIT_RATIO * desired_force_n),
        "start_x_mm": x0,
        "start_y_mm": start_y,
        "start_z_mm": z0,
        "retract_y_mm": retract_y,
        "workspace_min_y_mm": float(low_y),
        "workspace_max_y_mm": float(high_y),
        "probe_max_depth_mm": _tidy(PROBE_DEPTH_SHARE * thickness),
        "probe_dwell_s": _tidy(max(1.5, 4.0 * sponge.relaxation_time_s)),
    }


def _probe_noise_settings(noise_n: float) -> dict[str, float]:
    """The probe's samples and contact threshold for a sensor of noise std ``noise_n`` (N)."""
    samples = round(PROBE_SAMPLES * (noise_n / TODAY_NOISE_N) ** 2)
    return {
        "probe_samples": float(min(MAX_PROBE_SAMPLES, max(PROBE_SAMPLES, samples))),
        "probe_contact_force_n": _tidy(max(1.0, CONTACT_NOISE_RATIO * noise_n)),
    }


def draw_hidden_cell(
    seed: int, index: int, ranges: HiddenCellRanges | None = None
) -> HiddenCell:
    """Draw cell ``index`` (1-based) of generator ``seed`` over ``ranges``."""
    r = ranges or HiddenCellRanges()
    rng = np.random.default_rng([seed, index])
    base = SpongeParams()
    wear_rate = _log_uniform(rng, r.wear_rate)
    wear_amplitude = _uniform(rng, r.wear_amplitude)
    nonlinear = bool(rng.random() < r.nonlinear_share)
    hysteresis = bool(rng.random() < r.hysteresis_share)
    friction = bool(rng.random() < r.friction_share)
    sponge = replace(
        base,
        stiffness_n_per_mm=_log_uniform(rng, r.stiffness_n_per_mm),
        surface_y_mm=_uniform(rng, r.surface_y_mm),
        softening=_tidy(base.softening * wear_amplitude),
        set_mm=_tidy(base.set_mm * wear_amplitude),
        softening_passes=_tidy(base.softening_passes / wear_rate),
        set_passes=_tidy(base.set_passes / wear_rate),
        relaxation_ratio=_uniform(rng, r.relaxation_ratio),
        relaxation_time_s=_uniform(rng, r.relaxation_time_s),
        stiffening_exponent=_uniform(rng, r.stiffening_exponent) if nonlinear else 1.0,
        hysteresis_loss=_uniform(rng, r.hysteresis_loss) if hysteresis else 0.0,
        friction_coefficient=_uniform(rng, r.friction_coefficient) if friction else 0.0,
    )
    lag_s = _log_uniform(rng, r.lag_s)
    noise_n = _log_uniform(rng, r.noise_n)
    desired_force_n = _tidy(_uniform(rng, r.desired_force_kgf) * KGF_N)
    # the periodic shapes and the acceleration from streams of their own, so that adding
    # them left every other draw of a seed as it was
    shapes = np.random.default_rng([seed, index, 2])
    if shapes.random() < r.shaped_share:
        sponge = replace(
            sponge,
            waviness_mm=_uniform(shapes, r.waviness_mm),
            waviness_wavelength_mm=_uniform(shapes, r.waviness_wavelength_mm),
            stiffness_variation=_uniform(shapes, r.stiffness_variation),
            stiffness_wavelength_mm=_uniform(shapes, r.stiffness_wavelength_mm),
        )
    sponge, derived = _derive(sponge, desired_force_n)
    derived.update(_probe_noise_settings(noise_n))
    accel_mm_s2 = _log_uniform(np.random.default_rng([seed, index, 1]), r.accel_mm_s2)
    return HiddenCell(
        name=f"cell-{index:02d}",
        sponge=sponge,
        lag_s=lag_s,
        noise_n=noise_n,
        desired_force_n=desired_force_n,
        wear_rate=wear_rate,
        wear_amplitude=wear_amplitude,
        derived=derived,
        accel_mm_s2=accel_mm_s2,
    )


def cell_config(cell: HiddenCell) -> dict[str, Any]:
    """The cell config (TOML tables) of a hidden cell: every sponge parameter written out."""
    d = cell.derived
    noise = cell.noise_n
    limits = SafetyLimits()
    return {
        "task": {
            "desired_force_n": cell.desired_force_n,
            "start_mm": [d["start_x_mm"], d["start_y_mm"], d["start_z_mm"]],
            "retract_y_mm": d["retract_y_mm"],
        },
        "safety": {
            "max_force_n": d["max_force_n"],
            "workspace_min_mm": [limits.workspace_min_mm[0], d["workspace_min_y_mm"],
                                 limits.workspace_min_mm[2]],
            "workspace_max_mm": [limits.workspace_max_mm[0], d["workspace_max_y_mm"],
                                 limits.workspace_max_mm[2]],
        },
        "probe": {
            "max_depth_mm": d["probe_max_depth_mm"],
            "dwell_s": d["probe_dwell_s"],
            "samples": int(d["probe_samples"]),
            "contact_force_n": d["probe_contact_force_n"],
        },
        "filter": {"measurement_variance_n2": _tidy(noise * noise)},
        "emulator": {
            "sponge": asdict(cell.sponge),
            "arm": {"lag_s": cell.lag_s, "accel_mm_s2": cell.accel_mm_s2},
            "sensor": {"noise_std": [noise, noise, noise] + [_tidy(noise / 10)] * 3},
        },
    }


def truth(cell: HiddenCell, seed: int, ranges: HiddenCellRanges) -> dict[str, Any]:
    """The hidden truth of a cell as JSON-able values: every drawn and derived parameter."""
    return {
        "name": cell.name,
        "generator": {"module": MODULE, "seed": seed, "ranges": asdict(ranges)},
        "sponge": asdict(cell.sponge),
        "model": {
            "nonlinear": cell.sponge.stiffening_exponent != 1.0,
            "hysteresis": cell.sponge.hysteresis_loss != 0.0,
            "friction": cell.sponge.friction_coefficient != 0.0,
            "shaped": any(getattr(cell.sponge, n) != getattr(SpongeParams(), n) for n in SHAPES),
        },
        "arm": {"lag_s": cell.lag_s, "accel_mm_s2": cell.accel_mm_s2},
        "sensor": {"noise_n": cell.noise_n},
        "task": {"desired_force_n": cell.desired_force_n,
                 "desired_force_kgf": cell.desired_force_n / KGF_N},
        "wear": {"rate": cell.wear_rate, "amplitude": cell.wear_amplitude},
        "derived": cell.derived,
    }


def write_hidden_cells(
    count: int, seed: int, out: Path, ranges: HiddenCellRanges | None = None
) -> list[Path]:
    """Draw ``count`` cells of generator ``seed`` into ``out``; return the configs' paths.

    Each config is loaded back with the run's own loader before this returns,
    so a cell that the run would refuse is an error here, not on the run.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"count = {count!r}: a whole number of cells >= 1")
    r = ranges or HiddenCellRanges()
    out.mkdir(parents=True, exist_ok=True)
    paths, index = [], []
    for i in range(1, count + 1):
        cell = draw_hidden_cell(seed, i, r)
        path = out / f"{cell.name}.toml"
        header = (f"# Hidden cell {cell.name} of generator seed {seed} ({MODULE}).\n"
                  f"# Truth: {cell.name}.truth.json. Run: forcelearn run --config {path.name}\n")
        path.write_text(header + tomli_w.dumps(cell_config(cell)), encoding="utf-8")
        load_cell_config(path)  # the run's own checks (limits, workspace, keys)
        facts = truth(cell, seed, r)
        (out / f"{cell.name}.truth.json").write_text(json.dumps(facts, indent=2) + "\n",
                                                     encoding="utf-8")
        paths.append(path)
        index.append({"config": path.name, "truth": f"{cell.name}.truth.json", **facts["model"]})
    manifest = {"seed": seed, "count": count, "ranges": asdict(r), "cells": index}
    (out / "hidden-cells.json").write_text(json.dumps(manifest, indent=2) + "\n",
                                           encoding="utf-8")
    return paths


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m forcelearn.tools.twin.hidden_cells --count N --seed S --out DIR``."""
    parser = argparse.ArgumentParser(
        prog=f"python -m {MODULE}",
        description="Draw hidden emulated cells (cell configs + their truth) for checking twins.",
    )
    parser.add_argument("--count", type=int, default=30, help="cells to draw (default 30)")
    parser.add_argument("--seed", type=int, default=1, help="generator seed (default 1)")
    parser.add_argument("--out", type=Path, required=True, help="folder to write them to")
    parser.add_argument("--shaped", type=float, default=0.0, metavar="SHARE",
                        help="share of the cells whose strip gets periodic shapes of its own "
                             "(waviness, stiffness variation; default 0: the defaults)")
    args = parser.parse_args(argv)
    if args.count < 1:
        parser.error(f"--count {args.count}: at least 1")
    if not 0.0 <= args.shaped <= 1.0:
        parser.error(f"--shaped {args.shaped}: a share in [0, 1]")
    paths = write_hidden_cells(args.count, args.seed, args.out,
                               HiddenCellRanges(shaped_share=args.shaped))
    print(f"{len(paths)} hidden cells in {args.out} (seed {args.seed})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
