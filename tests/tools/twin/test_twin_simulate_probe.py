"""The in-process simulated run (``forcelearn bench twin``) records the surface probe too."""

from __future__ import annotations

import math

from forcelearn.tools.benchmarks.twin import PROBE_POINTS
from forcelearn.tools.experiments.records import PROBE_TRIAL
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.simulate import SimulatedRun, simulate_run


def test_the_probe_comes_first_with_presses_and_dwell_rereads() -> None:
    """As a run directory: trial -1 first, presses at every point, re-reads after dwells."""
    run = SimulatedRun(trials=2, probe_points=PROBE_POINTS)
    records = simulate_run(run, seed=1)
    probe = records[0]
    assert probe.trial == PROBE_TRIAL
    assert [t.trial for t in records[1:]] == [1, 2]
    assert {s.stage for s in probe.steps} == {"probe"}
    assert {s.index for s in probe.steps} == set(range(len(PROBE_POINTS)))
    desired = run.desired_force_n
    for point in range(len(PROBE_POINTS)):
        forces = [s.burst.mean_n for s in probe.steps if s.index == point and s.burst]
        assert max(forces) > desired  # pressed past the working force
    rereads = [s for s in probe.steps
               if s.move.start_s == s.move.in_position_s == s.move.settled_s]
    assert rereads and all(s.burst is not None and math.isnan(s.move.reached_mm[0])
                           for s in rereads)
    data = to_arrays(records)  # the fit reads them
    assert data.trial[0] == PROBE_TRIAL


def test_without_probe_points_there_is_no_probe() -> None:
    """The default simulated run is unchanged: no probe records."""
    records = simulate_run(SimulatedRun(trials=1), seed=1)
    assert [t.trial for t in records] == [1]
