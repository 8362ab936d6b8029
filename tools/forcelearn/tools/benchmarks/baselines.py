"""Benchmark: the cost of one step of the baselines study, per method, on the emulated cell.

Runs a method of :mod:`.baselines_study` (``run_baseline``: ``forcelearn/Surface-v0``
on the emulated cell through the real drivers, the surface probe first) for one
seed and ``--long`` trials, and times the trials from ``--short`` on inside that
run: what every run pays once (opening the cell, the probe, imports, the first
trials) is left out, so the figure is what each further step costs: CPU time
(this process) and wall time, in ms per step. The study's wall time is about its
steps times the wall time per step, divided by the workers. The figures depend on
the host's load; run it on an idle machine.
"""

from __future__ import annotations

import argparse
import time
from typing import Any, SupportsFloat

import gymnasium

from forcelearn.tools.study.baselines import METHODS, BaselinesConfig, run_baseline


class TrialTimer(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Stamps CPU and wall time at the start of trial ``first`` and after every later step.

    Attributes:
        steps: environment steps taken since trial ``first`` began.
        cpu_s, wall_s: CPU and wall time from trial ``first``'s reset to the last step, s.
    """

    def __init__(self, env: gymnasium.Env[Any, Any], first: int):
        super().__init__(env)
        self.first = first
        self.trial = -1
        self.steps = 0
        self.cpu_s = self.wall_s = 0.0
        self._cpu0 = self._wall0 = 0.0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Begin a trial; the clock starts with trial ``first``."""
        self.trial += 1
        if self.trial == self.first:
            self._cpu0, self._wall0 = time.process_time(), time.perf_counter()
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """One step; timed from trial ``first`` on."""
        result = self.env.step(action)
        if self.trial >= self.first:
            self.steps += 1
            self.cpu_s = time.process_time() - self._cpu0
            self.wall_s = time.perf_counter() - self._wall0
        return result


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench baselines``."""
    parser.add_argument("--methods", default="pi,cma",
                        help="comma-separated methods (srv, pi, ilc, cma; default pi,cma)")
    parser.add_argument("--variant", default="default", help="cell variant (default: default)")
    parser.add_argument("--short", type=int, default=5,
                        help="trials run before the clock starts (default 5)")
    parser.add_argument("--long", type=int, default=25, help="trials of the run (default 25)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the run")


def timed_run(method: str, variant: str, trials: int, seed: int, first: int) -> TrialTimer:
    """Run ``trials`` trials of ``method``; the timer holds trials ``first`` on."""
    timers: list[TrialTimer] = []

    def wrap(env: gymnasium.Env[Any, Any]) -> gymnasium.Env[Any, Any]:
        timers.append(TrialTimer(env, first))
        return timers[-1]

    run_baseline(BaselinesConfig(method=method, variant=variant, trials=trials), seed, wrap)
    return timers[0]


def run(args: argparse.Namespace) -> int:
    """Print CPU and wall ms per step of each method, over trials ``--short`` to ``--long``."""
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = [m for m in methods if m not in METHODS or m == "sac"]
    if unknown or not 0 < args.short < args.long:
        raise SystemExit(
            f"bench baselines: methods from srv, pi, ilc, cma (got {', '.join(unknown) or '-'}), "
            f"and 0 < --short < --long (got {args.short}, {args.long})"
        )
    for method in methods:
        timer = timed_run(method, args.variant, args.long, args.seed, args.short)
        if timer.steps == 0:
            print(f"{method}: the run stopped before trial {args.short}; no figure")
            continue
        print(
            f"{method} ({args.variant}, seed {args.seed}): {timer.steps} steps in trials "
            f"{args.short}..{timer.trial}: {1000 * timer.cpu_s / timer.steps:.2f} ms CPU, "
            f"{1000 * timer.wall_s / timer.steps:.2f} ms wall per step"
        )
    return 0
