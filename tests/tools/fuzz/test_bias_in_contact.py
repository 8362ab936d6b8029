"""A bias step while the tool presses is caught by the move, recovered from, never read as force."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest

from forcelearn.site.config import load_cell_config
from forcelearn.tasks.bias_watch import MARGIN_N
from forcelearn.tools.experiments import surface_run as engine
from forcelearn.tools.experiments import surface_state as run_state
from forcelearn.tools.experiments.fault_recovery import read_events
from forcelearn.tools.fuzz.fault_campaign import cell_config, injecting
from forcelearn.tools.fuzz.fault_inject import Injector, Truth

SEED = 5
STEP = ("step", 3)


class Largest(random.Random):
    """Draws the largest bias jump upwards (the injector's sizes)."""

    def uniform(self, a: float, b: float) -> float:
        """The upper end."""
        return b

    def choice(self, seq: Any) -> Any:
        """The last one."""
        return seq[-1]


class Tracer(Injector):
    """Notes the cell's stage at every device call (tick)."""

    def __init__(self) -> None:
        super().__init__({}, random.Random(0))
        self.stages: list[tuple[str, int]] = []

    def _step(self) -> None:
        super()._step()
        self.stages.append(self.session.cell.stage)


def run(config: Path, folder: Path, injector: Injector) -> Truth:
    """One run of ``config`` in ``folder`` with ``injector``; the truth of its first session."""
    truths: list[Truth] = []
    with injecting(injector, 1.0, truths):
        run_, checkpoint = run_state.prepare_run(config, folder, None, SEED, resume=False)
        engine.execute(run_, checkpoint)
    return truths[0]


def test_a_bias_jump_in_contact_is_detected_retracted_from_and_retared(tmp_path: Path) -> None:
    """Clean: no alarm. Jump 8 N just before step 3's move: found, zero moved, trial again."""
    config = cell_config("link+jr3", tmp_path, trials=2, steps=4, probe=False)
    tracer = Tracer()
    clean = run(config, tmp_path / "clean", tracer)
    assert read_events(tmp_path / "clean") == []  # no false alarm on a fault-free run
    assert clean.readings > 0 and not clean.bad_readings
    tick = tracer.stages.index(STEP) + 1  # the move to step 3 of the first trial

    injector = Injector({tick: [("sensor", "bias_jump")]}, Largest())
    truth = run(config, tmp_path / "jump", injector)
    assert injector.fired and injector.fired[0].in_contact
    events = read_events(tmp_path / "jump")
    # step 3 eases off: a drop there may be a foam's unloading branch, so it is judged when
    # the tool presses back to that depth (then SensorSuspect), else at the trial's zero check
    assert [(e["error"], e["action"]) for e in events] in ([("SensorSuspect", "resumed")],
                                                           [("ZeroMoved", "voided")])
    assert abs(events[0]["free_reading_n"]) > MARGIN_N
    assert truth.max_contact_n <= clean.max_contact_n + 1.0  # pressed no deeper on it
    # + the recovery's, and the two checks of the first press made twice after it
    assert truth.zeros_in_contact == 0 and truth.zeros == clean.zeros + 3
    assert not truth.bad_readings  # no reading after the jump was taken for force


class Sized(random.Random):
    """Draws a bias jump of ``size_n`` (N, signed) for the injector."""

    def __init__(self, size_n: float) -> None:
        super().__init__(0)
        self.size_n = size_n

    def uniform(self, a: float, b: float) -> float:
        """The jump's size."""
        return abs(self.size_n)

    def choice(self, seq: Any) -> Any:
        """The jump's sign."""
        return seq[0] if self.size_n < 0 else seq[-1]


class OnStage(Injector):
    """A bias jump at the first device call of each given stage, each after the last's event."""

    def __init__(self, jumps: list[tuple[tuple[str, int], float]], folder: Path) -> None:
        super().__init__({}, random.Random(0))
        self.jumps = jumps
        self.events = lambda: len(read_events(folder))

    def _step(self) -> None:
        super()._step()
        if (self.jumps and self.session.cell.stage == self.jumps[0][0]
                and self.events() == len(self.fired)):
            self.rng = Sized(self.jumps.pop(0)[1])
            self._fire("sensor", "bias_jump")


def test_bias_jumps_the_watch_cannot_see_void_the_trial_and_no_reading_is_used(
    tmp_path: Path,
) -> None:
    """Jumps in free space before the first press, and under the margin in contact: voided."""
    config = cell_config("link+jr3", tmp_path, trials=2, steps=4, probe=False)
    injector = OnStage([(("approach", 0), -6.9), (STEP, 0.6 * MARGIN_N)], tmp_path / "unseen")
    truth = run(config, tmp_path / "unseen", injector)
    assert len(injector.fired) == 2 and injector.fired[1].in_contact
    events = read_events(tmp_path / "unseen")
    assert [(e["error"], e["action"]) for e in events] == [("ZeroMoved", "voided")] * 2
    assert sum(truth.voided_bad.values()) > 0  # the readings were off, and set aside
    assert truth.readings > 0 and not truth.bad_readings  # none of them was used
    axis = truth.session.cell.force_filter.config.axis
    sigma_n = truth.session.sensor_emulator.model.params.noise_std[axis]
    assert truth.worst_used_n <= 3 * sigma_n  # every used reading within 3 sigma of the truth
    assert truth.zeros_in_contact == 0


def test_a_net_ft_bias_step_of_a_few_sigma_is_voided_not_kept(tmp_path: Path) -> None:
    """6 sigma of Net F/T noise in free space before the first press: the zero check voids it.

    Under the old bound's 0.5 N floor (10 sigma of this sensor) it was kept, and every
    reading of that trial was off by it.
    """
    config = cell_config("link+netft", tmp_path, trials=1, steps=4, probe=False)
    sigma_n = load_cell_config(config).filter.measurement_variance_n2 ** 0.5  # the box's R
    injector = OnStage([(("approach", 0), -6.0 * sigma_n)], tmp_path / "small")
    truth = run(config, tmp_path / "small", injector)
    assert len(injector.fired) == 1
    events = read_events(tmp_path / "small")
    assert [(e["error"], e["action"]) for e in events] == [("ZeroMoved", "voided")]
    assert truth.readings > 0 and truth.worst_used_n <= 3 * sigma_n
    assert truth.sigma_n == pytest.approx(sigma_n) and truth.beyond_3sigma == 0
