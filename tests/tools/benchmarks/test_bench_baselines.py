"""``forcelearn bench baselines``: the per-step figure of the trials after the first ones."""

from __future__ import annotations

import argparse
import re

import gymnasium
import numpy as np
import pytest

from forcelearn.tools.benchmarks import baselines as bench_baselines


def _args(**overrides: object) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    bench_baselines.add_arguments(parser)
    args = parser.parse_args([])
    for key, value in overrides.items():
        setattr(args, key, value)
    return args


def test_prints_cpu_and_wall_per_step_of_the_extra_trials(capsys: pytest.CaptureFixture[str]):
    """One ILC trial beyond the first: a figure per step, CPU and wall, both positive."""
    assert bench_baselines.run(_args(methods="ilc", short=1, long=2)) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    match = re.fullmatch(r"ilc \(default, seed 1\): (\d+) steps in trials 1\.\.1: "
                         r"([\d.]+) ms CPU, ([\d.]+) ms wall per step", line)
    assert match is not None, line
    steps, cpu_ms, wall_ms = int(match[1]), float(match[2]), float(match[3])
    assert 0 < steps <= 20  # one 20-step trial more
    assert cpu_ms > 0 and wall_ms > 0


@pytest.mark.parametrize("overrides", [{"methods": "sac"}, {"methods": "nope"},
                                       {"short": 5, "long": 5}])
def test_bad_options_are_refused_before_any_run(overrides: dict[str, object]):
    """SAC, unknown methods and an empty trial range stop with a message that says why."""
    with pytest.raises(SystemExit, match="bench baselines"):
        bench_baselines.run(_args(**overrides))


class _TwoStepEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """A trial of two steps, the second one truncated."""

    observation_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))
    action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return np.zeros(1, dtype=np.float32), {}

    def step(self, action):
        self.t += 1
        return np.zeros(1, dtype=np.float32), 0.0, False, self.t == 2, {}


def test_the_timer_counts_only_the_steps_from_its_first_trial_on():
    """Three two-step trials timed from trial 1: four steps, and a clock that ran."""
    timer = bench_baselines.TrialTimer(_TwoStepEnv(), first=1)
    for _ in range(3):
        timer.reset()
        truncated = False
        while not truncated:
            truncated = timer.step(np.zeros(1, dtype=np.float32))[3]
    assert timer.steps == 4 and timer.trial == 2
    assert timer.wall_s > 0 and timer.cpu_s >= 0
