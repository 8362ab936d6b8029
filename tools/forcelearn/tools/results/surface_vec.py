r"""How closely ``forcelearn/SurfaceVec-v0`` (numpy) follows ``forcelearn/Surface-v0`` (the wires).

For each seed, one wire-level cell runs its surface probe; both envs then
start from that probe (the same map, passes and sensor zeroing time) and run
the same policies for the same trials:

=========  ====================================================================
``fixed``  the probe's path (the offsets where its fits expect the desired
           force), every trial the same
``pi``     the baselines' PI force control (``forcelearn.baselines.controllers``)
``srv``    the paper's learner over BOXES, warm-started from the probe
           (``[run] learner_start = "probe"``)
=========  ====================================================================

Agreement, per policy and trial index: the mean over seeds of the per-trial
force RMS (N) of the numpy env against the wire-level cell's, the difference
compared with the wire-level cell's own spread over seeds (its standard
deviation: the noise a seed brings), and the failed trials of each. A policy
agrees when every trial's difference is within twice the wire-level cell's
pooled spread (the root mean square over the trials of its standard
deviations): :func:`agreement`.

    python -m forcelearn.tools.results.surface_vec --seeds 10 --trials 4 \
        --out docs/results/surface-vec.md

(or halves in parallel: ``--first-seed 0 --seeds 5 --json a.json`` and
``--first-seed 5 --seeds 5 --json b.json``, then ``--combine a.json b.json --out ...``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

POLICIES = ("fixed", "pi", "srv")


class FixedPath:
    """The probe's path, every trial the same (a baselines ``Controller``)."""

    name = "fixed"

    def __init__(self, env: Any) -> None:
        self.path = np.zeros(int(env.task_steps_per_trial))
        self.max_offset_mm = 1.0
        self._step = 0

    def begin(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Take the path from reset's info (the probe's), once."""
        from forcelearn.baselines.controllers import CellPrior

        prior = CellPrior.from_info(info, 15.0)
        self.path = prior.first_path_mm(len(self.path), 0.0)
        self.max_offset_mm = prior.max_offset_mm
        self._step = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The path's offset of this step, as an action."""
        offset = self.path[min(self._step, len(self.path) - 1)]
        self._step += 1
        return np.array([offset / self.max_offset_mm])

    def observe(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Nothing is learned."""

    def end(self, record: Any) -> None:
        """Nothing is carried."""


def controller(policy: str, env: Any, seed: int) -> Any:
    """The controller of ``policy`` on ``env`` (unwrapped)."""
    from forcelearn.baselines.controllers import ForceController, SRVController

    if policy == "fixed":
        return FixedPath(env)
    if policy == "pi":
        return ForceController(env)
    if policy == "srv":
        return SRVController(env, env.config.learner, seed, start="probe")
    raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")


@dataclass(frozen=True)
class Runs:
    """Per-trial force RMS (N) and failures of one env kind: [seed][trial]."""

    rms_n: np.ndarray
    failed: np.ndarray
    wall_s: float


def run_both(seed: int, policies: tuple[str, ...], trials: int,
             config: Any = None) -> dict[str, dict[str, tuple[list[float], list[bool], float]]]:
    """Run every policy on both envs from one probe; {policy: {kind: (rms, failed, wall)}}."""
    from forcelearn.baselines.runner import run_controller
    from forcelearn.envs.surface import SurfaceEnv
    from forcelearn.envs.surface_vec import SurfaceSimEnv, probe_map

    probed = probe_map(config, seed)
    makers: dict[str, Callable[[], Any]] = {
        "wire": lambda: SurfaceEnv(config, seed=seed),
        "numpy": lambda: SurfaceSimEnv(config, seed=seed, probed=probed),
    }
    out: dict[str, dict[str, tuple[list[float], list[bool], float]]] = {}
    for policy in policies:
        out[policy] = {}
        for kind, make in makers.items():
            env = make()
            try:
                started = time.perf_counter()
                recorder = run_controller(env, controller(policy, env, seed), trials, seed,
                                          stop_early=False)
                wall = time.perf_counter() - started
            finally:
                env.close()
            out[policy][kind] = ([r.force_rms_n for r in recorder.records],
                                 [r.failed for r in recorder.records], wall)
    return out


def agreement(wire: np.ndarray, vec: np.ndarray) -> tuple[float, float]:
    """(largest |mean difference| over trials, the wire cell's pooled sd), N; [seed, trial]."""
    differences = np.abs(vec.mean(axis=0) - wire.mean(axis=0))
    pooled = float(np.sqrt(np.mean(wire.var(axis=0, ddof=1))))
    return float(differences.max()), pooled


def table(results: list[dict[str, dict[str, tuple[list[float], list[bool], float]]]],
          policies: tuple[str, ...]) -> tuple[str, dict[str, float]]:
    """The Markdown table and, per policy, the worst |difference| / wire spread over trials."""
    lines = ["| policy | trial | wire RMS N (mean ± sd over seeds) | numpy RMS N | difference N "
             "| difference / wire sd | failed wire / numpy |", "|---|---|---|---|---|---|---|"]
    worst: dict[str, float] = {}
    for policy in policies:
        wire = np.array([r[policy]["wire"][0] for r in results])
        vec = np.array([r[policy]["numpy"][0] for r in results])
        wire_failed = np.array([r[policy]["wire"][1] for r in results])
        vec_failed = np.array([r[policy]["numpy"][1] for r in results])
        ratios = []
        for t in range(wire.shape[1]):
            sd = float(wire[:, t].std(ddof=1))
            diff = float(vec[:, t].mean() - wire[:, t].mean())
            ratio = abs(diff) / sd if sd > 0 else math.inf
            ratios.append(ratio)
            lines.append(
                f"| {policy} | {t} | {wire[:, t].mean():.3f} ± {sd:.3f} | "
                f"{vec[:, t].mean():.3f} ± {vec[:, t].std(ddof=1):.3f} | {diff:+.3f} | "
                f"{ratio:.2f} | {int(wire_failed[:, t].sum())} / {int(vec_failed[:, t].sum())} |")
        largest, pooled = agreement(wire, vec)
        worst[policy] = largest / pooled
    return "\n".join(lines), worst


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (or combine earlier runs' JSON) and write the results page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--policies", nargs="*", default=list(POLICIES), choices=POLICIES)
    parser.add_argument("--json", type=Path, help="also write the per-seed results here")
    parser.add_argument("--combine", type=Path, nargs="*", default=[],
                        help="make the page from these --json files instead of running")
    parser.add_argument("--out", type=Path, help="write the Markdown table here")
    args = parser.parse_args(argv)
    policies = tuple(args.policies)
    results: list[dict[str, Any]] = []
    for path in args.combine:
        results += json.loads(path.read_text())
    for seed in range(args.first_seed, args.first_seed + (0 if args.combine else args.seeds)):
        results.append(run_both(seed, policies, args.trials))
        if args.json:
            args.json.write_text(json.dumps(results))
        print(f"seed {seed} done", flush=True)
    walls = {kind: sum(r[p][kind][2] for r in results for p in policies)
             for kind in ("wire", "numpy")}
    text, worst = table(results, policies)
    summary = "\n".join(
        f"- {p}: largest |difference| / the wire cell's pooled sd: {w:.2f} "
        f"({'agrees' if w <= 2.0 else 'does NOT agree'}: within 2)" for p, w in worst.items())
    page = (f"{len(results)} seeds.\n\n{text}\n\n{summary}\n\nwall time of the runs: wire "
            f"{walls['wire']:.0f} s, numpy {walls['numpy']:.1f} s\n")
    print(page)
    if args.out:
        args.out.write_text(page)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
