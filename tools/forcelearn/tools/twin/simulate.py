"""Records of a §5-like run made in process by the emulator's own physics (no wires).

The twin's tests and benchmark need records from a cell whose parameters are
known. This module drives the same pieces the emulated cell is built of —
:class:`~forcelearn.emulators.physics.sponge.Sponge`,
:class:`~forcelearn.emulators.physics.arm_motion.ArmMotion` inside
:class:`~forcelearn.emulators.physics.cell.CellPhysics`, and the JR3's
:class:`~forcelearn.emulators.jr3.sensor_model.Jr3SensorModel` — through the
sequence of a §5 trial, and writes what a run records
(:mod:`forcelearn.records`):

1. from the retract plane (Y = ``retract_y_mm``) travel in Z to above the start
   (approach moves, no force read), then press in along Y in steps of at most
   ``max_step_mm``, one sample read after each intermediate step (the force
   guard) and a burst after the last;
2. ``steps`` control steps of ``z_step_mm`` with a Y command from a plain
   force-tracking rule plus exploration (what a learner mid-way does);
3. retreat along +Y to the retract plane (a pass of the sponge ends).

Time is the cell's: a move is sent, the arm runs on its tick grid until in
position, dwells ``settle_s``, then the burst's samples are taken every
``sample_period_s``. There is no wire latency, so this is the cell an
ideal link would see.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from forcelearn.devices import Pose, quaternion_to_matrix
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams, Jr3SensorModel
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams, stiffness_n_per_mm
from forcelearn.emulators.physics.sponge import surface_y_mm as sponge_surface_y_mm
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TareRecord, TrialRecords
from forcelearn.tools.experiments.records import PROBE_TRIAL

DOWN = (0.0, 1.0, 0.0, 0.0)
"""The §5 tool orientation (w, x, y, z): pointing down; the normal force is world +Y."""


def noise_only_sensor(noise_n: float = 0.0) -> Jr3ModelParams:
    """A JR3 model with ``noise_n`` (N, or N*m on the moments) on every axis, no bias, no drift."""
    return Jr3ModelParams(noise_std=(noise_n,) * 6, initial_bias=(0.0,) * 6,
                          bias_drift_per_sqrt_s=(0.0,) * 6)


@dataclass(frozen=True)
class SimulatedRun:
    """A §5-like run's settings (mm, s, N); defaults are the emulated cell's."""

    trials: int = 30
    steps: int = 20
    z_step_mm: float = -5.0
    start_mm: tuple[float, float, float] = (900.0, -4.0, 0.0)
    retract_y_mm: float = 15.0
    max_step_mm: float = 10.0
    settle_s: float = 0.05
    burst_samples: int = 40
    """Samples per burst (a run reads ~195 in 25 ms; fewer keep the tests fast)."""
    sample_period_s: float = 128.5e-6
    cutoff_hz: float = 125.0
    """The adapter's low-pass cut-off (colours the noise)."""
    desired_force_n: float = 19.6133
    exploration_mm: float = 0.8
    """Std of the random part of each Y command, mm."""
    tare_each_trial: bool = False
    zero_check_each_trial: bool = False
    """End each trial as the §5 run's zero check does: a burst read at the retract plane after
    the retreat, recorded on its last move, and a tare in software on its mean."""
    probe_points: tuple[float, ...] = ()
    """The surface probe before the trials, as fractions of the path (0: start Z, 1: end Z),
    in the order probed (empty: no probe); its records come first, as trial -1."""
    probe_samples: int = 16
    probe_dwell_s: float = 1.5
    probe_presses: int = 6
    probe_force_ratio: float = 1.25
    sponge: SpongeParams = field(default_factory=SpongeParams)
    motion: MotionParams = field(default_factory=MotionParams)
    sensor: Jr3ModelParams = field(default_factory=noise_only_sensor)
    """The sensor model (default: noiseless, no bias)."""


class _Recorder:
    """Drives the physics and writes records as the run engine would."""

    def __init__(self, run: SimulatedRun, seed: int, sponge: Sponge | None) -> None:
        self.run = run
        self.sponge = sponge or Sponge(run.sponge)
        start = Pose(run.start_mm[0], run.retract_y_mm, run.start_mm[2], DOWN)
        self.physics = CellPhysics(self.sponge, start)
        self.motion = ArmMotion(run.motion, start)
        self.physics.attach_motion(self.motion)
        self.sensor = Jr3SensorModel(run.sensor, np.random.default_rng(seed))
        self.rng = np.random.default_rng(seed + 1)
        self.now_s = 0.0
        self.target = start
        self.steps: list[StepRecord] = []
        self.tares: list[TareRecord] = []
        self._rotation = quaternion_to_matrix(DOWN)
        self._last_sample_s = 0.0
        self._wait_end_s = 0.0
        """The end of the last wait: what the engine records as the next move's start."""
        self.zero_n = 0.0
        """The software zero taken by the last zero check, N."""

    def _normal_n(self) -> float:
        self.physics.advance_to(self.now_s)
        counts = self.sensor.measure(
            self.physics.true_wrench(), self.now_s - self._last_sample_s, self.run.cutoff_hz
        )
        self._last_sample_s = self.now_s
        full_scale = self.run.sensor.full_scales[1]
        return -counts[1] * full_scale / 16384.0 - self.zero_n  # [filter] axis 1, sign -1

    def move(self, trial: int, index: int, kind: str, target: Pose, samples: int) -> None:
        """Command ``target``, wait in position (+ settle), read ``samples`` (0: none).

        The command leaves now (after any burst read since the last wait); the record's
        start is the last wait's end, as the run engine records it (docs/records.md).
        """
        start_s = self._wait_end_s
        self.motion.command(target, self.now_s)
        self.target = target
        tick = self.run.motion.tick_s
        t = self.now_s
        while True:
            t = (math.floor(t / tick + 1e-9) + 1) * tick
            self.physics.advance_to(t)
            if self.motion.in_position:
                break
        in_position_s = t
        reached = self.motion.pose
        settle = self.run.settle_s if samples > 1 else 0.0
        self.now_s = in_position_s + settle
        self._wait_end_s = self.now_s
        self.physics.advance_to(self.now_s)
        move = MoveRecord(
            (target.x_mm, target.y_mm, target.z_mm),
            (reached.x_mm, reached.y_mm, reached.z_mm),
            start_s, in_position_s, self.now_s,
        )
        burst = self._burst(samples) if samples else None
        self.steps.append(StepRecord(trial, index, kind, move, burst))

    def _burst(self, samples: int) -> BurstRecord:
        first_s = self.now_s
        values = []
        for i in range(samples):
            if i:
                self.now_s += self.run.sample_period_s
            values.append(self._normal_n())
        data = np.array(values)
        return BurstRecord(
            float(data.mean()), float(data.std()), values[0], values[-1], samples, first_s,
            self.now_s - first_s, float(data.mean()),
        )

    def move_in_steps(self, trial: int, kind: str, goal: Pose, guard: bool, last: int,
                      index: int = 0) -> None:
        """Straight steps of at most ``max_step_mm`` as :meth:`Cell.move_in_steps` cuts them."""
        here = self.target
        distance = math.dist(
            (here.x_mm, here.y_mm, here.z_mm), (goal.x_mm, goal.y_mm, goal.z_mm)
        )
        if distance == 0.0:
            return
        count = max(1, math.ceil(distance / (0.99 * self.run.max_step_mm)))
        for i in range(1, count + 1):
            f = i / count
            pose = Pose(here.x_mm + f * (goal.x_mm - here.x_mm),
                        here.y_mm + f * (goal.y_mm - here.y_mm),
                        here.z_mm + f * (goal.z_mm - here.z_mm), DOWN)
            samples = last if i == count else (1 if guard else 0)
            self.move(trial, index, kind, pose, samples)

    def hold(self, trial: int, index: int, dwell_s: float, samples: int) -> None:
        """Hold the pose ``dwell_s`` and read again, recorded as the probe's re-read.

        The record's move is the pose held (reached unknown), its three times the
        burst's start, as the run engine writes a probe's re-read (docs/records.md).
        """
        self.now_s += dwell_s
        self._wait_end_s = self.now_s
        pose = self.target
        here = (pose.x_mm, pose.y_mm, pose.z_mm)
        move = MoveRecord(here, (math.nan,) * 3, self.now_s, self.now_s, self.now_s)
        self.steps.append(StepRecord(trial, index, "probe", move, self._burst(samples)))

    def probe(self, trial: int) -> None:
        """The surface probe as the run engine does it, at each of ``run.probe_points``.

        At each point: down the retract plane, a free-space reading; then 1 mm steps
        towards the surface (a burst each) until the force passes 1 N; a re-read now
        and after the dwell; then presses to ``probe_force_ratio`` x the desired force,
        each read after the move and again after the dwell; back to the retract plane.
        """
        run = self.run
        x0, _, z0 = run.start_mm
        z_end = z0 + run.steps * run.z_step_mm
        for index, fraction in enumerate(run.probe_points):
            z = z0 + fraction * (z_end - z0)
            self.move_in_steps(trial, "probe", Pose(x0, run.retract_y_mm, z, DOWN), False,
                               run.probe_samples, index)
            self.hold(trial, index, 0.0, run.probe_samples)
            y = run.retract_y_mm
            while True:
                y -= 1.0
                self.move(trial, index, "probe", Pose(x0, y, z, DOWN), run.burst_samples)
                if self.steps[-1].burst is not None and self.steps[-1].burst.mean_n > 1.0:
                    break
                if y < run.retract_y_mm - 60.0:
                    return  # no surface: the probe gives up
            self.hold(trial, index, 0.0, run.probe_samples)
            self.hold(trial, index, run.probe_dwell_s, run.probe_samples)
            deepest = _path_y_mm(run.sponge, z, run.probe_force_ratio * run.desired_force_n)
            for press in range(1, run.probe_presses):
                target = y + press / (run.probe_presses - 1) * (deepest - y)
                self.move(trial, index, "probe", Pose(x0, target, z, DOWN), run.probe_samples)
                self.hold(trial, index, run.probe_dwell_s, run.probe_samples)
            self.move_in_steps(trial, "probe", Pose(x0, run.retract_y_mm, z, DOWN), False, 0,
                               index)

    def zero_check(self, trial: int) -> None:
        """A tare in software on the last step's burst (read in free space, recorded)."""
        step = self.steps[-1]
        assert step.burst is not None  # the retreat's last move read one
        reading = step.burst.mean_n
        self.zero_n += reading
        pose = self.target
        self.tares.append(TareRecord(trial, step.move.settled_s,
                                     (pose.x_mm, pose.y_mm, pose.z_mm), reading, True))

    def tare(self, trial: int) -> None:
        """Zero the sensor in free space (the reading before is recorded)."""
        reading = self._burst(self.run.burst_samples).mean_n
        self.physics.advance_to(self.now_s)
        self.sensor.zero(self.physics.true_wrench())
        pose = self.target
        self.tares.append(
            TareRecord(trial, self.now_s, (pose.x_mm, pose.y_mm, pose.z_mm), reading, True)
        )


def _path_y_mm(params: SpongeParams, z_mm: float, force_n: float) -> float:
    """The Y that gives ``force_n`` on the fresh, relaxed sponge at ``z_mm`` (the rule's centre)."""
    return sponge_surface_y_mm(params, 0, z_mm) - force_n / stiffness_n_per_mm(params, 0, z_mm)


def simulate_run(run: SimulatedRun, seed: int = 0,
                 sponge: Sponge | None = None) -> list[TrialRecords]:
    """Return the records of ``run.trials`` §5-like trials on the emulated physics.

    ``sponge`` replaces the sponge of ``run.sponge`` (e.g. one with another force law);
    the Y commands still follow ``run.sponge``.
    """
    rec = _Recorder(run, seed, sponge)
    x0, _, z0 = run.start_mm
    trials = []
    if run.probe_points:
        rec.probe(PROBE_TRIAL)
        trials.append(TrialRecords(PROBE_TRIAL, list(rec.steps), []))
    for trial in range(1, run.trials + 1):
        first_step = len(rec.steps)
        first_tare = len(rec.tares)
        rec.move_in_steps(trial, "approach", Pose(x0, run.retract_y_mm, z0, DOWN), False, 0)
        if run.tare_each_trial:
            rec.tare(trial)
        offset = float(rec.rng.normal(0.0, 1.5))
        start_y = _path_y_mm(run.sponge, z0, 0.5 * run.desired_force_n) + offset
        rec.move_in_steps(trial, "approach", Pose(x0, start_y, z0, DOWN), True,
                          run.burst_samples)
        for step in range(1, run.steps + 1):
            z = z0 + step * run.z_step_mm
            y = _path_y_mm(run.sponge, z, run.desired_force_n) + offset * 0.5 ** step
            y += float(rec.rng.normal(0.0, run.exploration_mm))
            rec.move(trial, step, "step", Pose(x0, y, z, DOWN), run.burst_samples)
        here = rec.target
        rec.move_in_steps(trial, "retreat", Pose(x0, run.retract_y_mm, here.z_mm, DOWN),
                          False, run.burst_samples if run.zero_check_each_trial else 0)
        if run.zero_check_each_trial:
            rec.zero_check(trial)
        trials.append(TrialRecords(trial, rec.steps[first_step:], rec.tares[first_tare:]))
    return trials
