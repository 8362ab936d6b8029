"""The baselines page's table: one row per variant and method, its env and srv's start named."""

from __future__ import annotations

from typing import Any

import pytest

from forcelearn.errors import ConfigError
from forcelearn.tools.results.baselines_report import label, labels, report_rows
from forcelearn.tools.study.baselines import BaselinesConfig


def _row(method: str, env: str, start: str, seed: int, converged: int | None) -> dict[str, Any]:
    return {"variant": "default", "method": method, "env": env, "learner_start": start,
            "seed": seed, "converged_trial": converged, "cell_time_to_converge_s": None,
            "final_force_rms_n": 0.5 + seed, "worst_force_n": 21.0, "failures": seed,
            "steps": 400 + seed}


def test_rows_are_told_apart_by_env_and_by_srvs_start() -> None:
    """The two starts of srv and SAC on either env are rows of their own, in order."""
    rows = [_row("sac", "wire", "probe", 0, None), _row("srv", "wire", "cold", 0, 21),
            _row("sac", "vec", "probe", 0, None), _row("srv", "wire", "probe", 0, 0),
            _row("srv", "wire", "probe", 1, 0)]
    names = [label(r) for r in rows]
    assert names == ["sac (wire cell)", "srv, cold start", "sac (numpy cell)",
                     "srv, warm start", "srv, warm start"]
    assert all(name in labels() for name in names)
    table = report_rows(rows, trials=300)[2:]
    assert [line.split(" | ")[1] for line in table] == [
        "srv, warm start", "srv, cold start", "sac (numpy cell)", "sac (wire cell)"]
    warm = table[0].split(" | ")
    assert warm[2] == "2 / 2" and warm[-1] == "400 (400–401) |"


def test_the_study_refuses_an_unknown_env() -> None:
    """The env key is wire or vec."""
    with pytest.raises(ConfigError, match="env"):
        BaselinesConfig(env="gpu")


def test_the_study_starts_the_costliest_runs_first_and_keeps_a_probes_runs_together() -> None:
    """Chunks in falling cost; CMA-ES and SAC on one numpy cell's probe share one chunk."""
    from forcelearn.tools.study.grid import RunSpec
    from forcelearn.tools.study.runner import make_chunks
    from forcelearn.tools.study.tasks import get_task

    def spec(method: str, seed: int, **more: str) -> RunSpec:
        env = "vec" if method in ("cma", "sac") else "wire"
        pairs = {"method": method, "env": env, "learner_start": "probe", **more}
        return RunSpec("baselines", 300, seed, tuple(pairs.items()))

    specs = [spec(m, s) for s in (0, 1) for m in ("pi", "cma", "sac", "ilc")]
    specs.append(spec("srv", 0, learner_start="cold"))
    task = get_task("baselines")
    chunks = make_chunks(task, specs, slots=2, batch=32)
    assert task.cost is not None
    costs = [sum(task.cost(s) for s in chunk) for chunk in chunks]
    assert costs == sorted(costs, reverse=True)
    assert sorted(s.run_id for chunk in chunks for s in chunk) == sorted(s.run_id for s in specs)
    shared = [chunk for chunk in chunks if len(chunk) > 1]
    assert len(shared) == 2
    for chunk in shared:
        assert {dict(s.overrides)["method"] for s in chunk} == {"cma", "sac"}
        assert len({s.seed for s in chunk}) == 1
