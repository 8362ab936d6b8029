"""N emulated §5 cells stepped at once in numpy: the physics behind ``forcelearn/SurfaceVec-v0``.

The wire-level cell (``forcelearn/Surface-v0``) runs the real drivers against
the emulators; this batch runs the same physics without the wires, one numpy
expression over all N cells per phase of a step. What it takes from where:

==================  ==========================================================
the foam            :mod:`forcelearn.emulators.physics.sponge_law`, the one
                    law, on arrays: penetration, elastic depth, stiffness,
                    normal force, the relaxing part's exact ramp
                    (``relaxation_step``), wear by passes (softening, set)
the arm's timing    :class:`~forcelearn.emulators.physics.arm_motion.ArmMotion`
                    itself, run once per move length at construction: the
                    time from a command to *in position* (delay, trapezoid,
                    servo lag), tabulated and interpolated per step
the link's time     what the computer link at 9600 baud adds: the MOVE frame
                    before the arm takes it, the status polls before the
                    driver sees it in position and settled (constants below,
                    measured on the wire-level cell: of a step's 0.47 s of
                    cell time the arm takes 0.25, the link 0.17, the settle
                    0.05; docs/results/surface-vec.md)
the sensor          the JR3 model's noise on the normal axis: an
                    Ornstein-Uhlenbeck process (``noise_std``, the adapter's
                    cut-off), one count of quantisation, the bias's random walk
the filter          the step filter (:mod:`forcelearn.filtering.step_filter`):
                    each burst's generalised least-squares mean
                    (``burst_mean``'s weights), then one Kalman update after
                    the move's prediction (``move_change_std_n``)
the task            the §5 evaluation (``ForceEvaluation.ratio``, failure above
                    ``FAILURE_R``, ``SAFETY_R`` at the force limit), the output
                    map and its wear tracking (``SurfaceYOutput``'s rule)
==================  ==========================================================

Per step each cell moves 5 mm down and to its commanded Y (when the map has
an approach height, first to that much above it, then in: two moves): the relaxing part
decays through the arm's start delay, follows the elastic depth's ramp over
the travel, decays through the settle and the polls, and the burst of
``samples`` readings 1 ms apart is taken while it still decays. A trial's end
(failure or the path's end) retracts the roller: the foam recovers (q = 0) and
the pass is counted. A reset presses in at the start pose (the map's start
press plus its wear shift), settles, and reads the start force, from which
the map follows the wear.

Not modelled (refused at construction when configured on): the foam's
hysteresis and friction, a nonlinear foam is modelled; Net F/T and EGM cells
(the batch is the default computer-link + JR3 cell). The guard reads of
moves longer than ``max_step_mm`` update the filter as one-sample bursts in
the wire-level cell; here such moves are one ramp.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from forcelearn.devices import Pose
from forcelearn.emulators.physics import sponge_law as law
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.filtering.step_filter import burst_mean
from forcelearn.tasks.evaluation import FAILURE_R, SAFETY_R, ForceEvaluation

LINK_COMMAND_S = 0.095
"""Cell time from a move's start to the arm taking the command: the MOVE frame and its
answer on the computer link at 9600 baud, s (measured on the wire-level cell)."""
LINK_POLL_S = 0.042
"""Cell time from the arm's in-position to the driver's status poll that sees it, s
(the polls' quantisation at 9600 baud; measured on the wire-level cell)."""
SETTLE_POLL_S = 0.037
"""What the polls add to the settle before the driver sees it done, s (measured likewise)."""
RESET_TRAVEL_S = 4.2
"""Cell time of a reset's retract and travel out of contact, s (wire-level cell: the bias
drifts over it; the foam is out of contact and recovers)."""


FRACTIONS = np.linspace(0.0, 1.0, 41)
"""Fractions of a move's length at which :func:`motion_table` gives the time."""


@functools.lru_cache(maxsize=8)
def _motion_table(params: MotionParams, lengths_mm: tuple[float, ...]) -> np.ndarray:
    table = motion_table(params, np.asarray(lengths_mm))
    table.setflags(write=False)
    return table


def motion_table(params: MotionParams, lengths_mm: np.ndarray) -> np.ndarray:
    """Times (s) at which the tool has covered each of :data:`FRACTIONS` of a move.

    One row per length of ``lengths_mm`` (straight moves), one column per
    fraction; the last column is the time the robot is *in position* (the
    band reached and the path done), so a command at 0 is waited for until
    then. Runs :class:`ArmMotion` (the emulated arm: delay, trapezoid, servo
    lag) tick by tick.
    """
    table = np.zeros((len(lengths_mm), len(FRACTIONS)))
    start = Pose(0.0, 0.0, 0.0)
    for i, length in enumerate(lengths_mm):
        arm = ArmMotion(params, start)
        arm.command(Pose(0.0, float(length), 0.0), 0.0)
        times: list[float] = []
        progress: list[float] = []
        tick = 0
        while tick < 100_000:
            tick += 1
            arm.advance_to(tick * params.tick_s)
            times.append(tick * params.tick_s)
            progress.append(arm.pose.y_mm / length if length > 0 else 1.0)
            if arm.in_position:
                break
        covered = np.maximum.accumulate(np.asarray(progress))
        row = np.interp(FRACTIONS, covered, np.asarray(times), left=params.start_delay_s)
        row[-1] = times[-1]
        table[i] = np.maximum.accumulate(row)
    return table


@dataclass(frozen=True)
class BatchSpec:
    """Everything the batch needs, from a cell config and its output map (mm, s, N)."""

    sponge: law.SpongeParams
    motion: MotionParams
    evaluation: ForceEvaluation
    max_force_n: float
    steps: int
    z_step_mm: float
    start_y_mm: float
    start_z_mm: float
    retract_y_mm: float
    settle_s: float
    samples: int
    sample_period_s: float
    noise_std_n: float
    noise_cutoff_hz: float
    count_n: float
    """One count of the sensor's normal axis, N."""
    bias_drift_n_per_sqrt_s: float
    filter_variance_n2: float
    move_change_std_n: float
    max_step_mm: float
    centres_mm: tuple[float, ...]
    """The map's centre Y of every step (before its wear shift), mm."""
    max_offset_mm: float
    start_press_y_mm: float
    wear_stiffness_n_per_mm: float | None
    shift_range_mm: tuple[float, float] | None
    passes_at_start: int
    """Passes the sponge has when the first trial starts (the probe's presses)."""
    approach_mm: float = 0.0
    """Each step first stands this much shallower at its Z, then presses to its command
    (the map's ``approach_mm``; 0: straight there), mm."""
    bias_time_s: float = 0.0
    """Cell time from the sensor's zeroing to the first trial (its bias drifts meanwhile), s."""


class SurfaceBatch:
    """The state of N cells and their one step (see the module docstring).

    A step costs a fixed number of numpy calls over the N cells, whatever N:
    what depends only on the step index (Z, the share of the normal force
    along the sensor's Y, the map's centre) is tabulated per index at
    construction through the law's own functions; the cells that start a
    trial (a few per step at N = 64) retract and find the surface on their
    own subset; the three phases of a move's relaxation are one expression.
    """

    def __init__(self, spec: BatchSpec, num_envs: int, rng: np.random.Generator) -> None:
        p = spec.sponge
        if p.hysteresis_loss != 0.0 or p.friction_coefficient != 0.0:
            raise ValueError("the vectorised surface models neither hysteresis nor friction: "
                             "set emulator.sponge.hysteresis_loss and friction_coefficient to 0 "
                             "or use forcelearn/Surface-v0")
        self.spec, self.n, self.rng = spec, num_envs, rng
        self._dl = spec.max_step_mm * 1.05 / 63
        table = _motion_table(spec.motion, tuple((np.arange(64) * self._dl).tolist()))
        self._table = table
        self._flat = table.ravel()
        self._reach_first, self._in_position = table[:, 0].copy(), table[:, -1].copy()
        k = np.arange(spec.samples)
        self._sample_t = k * spec.sample_period_s
        correlation = math.exp(-2.0 * math.pi * spec.noise_cutoff_hz * spec.sample_period_s)
        basis = np.eye(spec.samples)
        self._weights = np.array([burst_mean(row.tolist(), correlation)[0] for row in basis])
        self._burst_factor = burst_mean(basis[0].tolist(), correlation)[1]
        # the adapter's low-pass on the noise, for a whole burst at once:
        # noise_k = keep^(k+1) * last + spread * sum_j<=k keep^(k-j) draw_j
        spread = spec.noise_std_n * math.sqrt(1.0 - correlation * correlation)
        lags = k[:, None] - k[None, :]
        self._mix = np.where(lags >= 0, spread * correlation ** np.maximum(lags, 0), 0.0).T
        self._carry = correlation ** (k + 1.0)
        self._mean_decay = float(np.exp(-self._sample_t / p.relaxation_time_s) @ self._weights)
        # per step index 0..steps: Z, the normal force's share along the sensor's Y, the centre
        index = np.arange(spec.steps + 1)
        self._z_of = spec.start_z_mm + index * spec.z_step_mm
        slope = law.surface_dy_dz(p, self._z_of)
        self._y_share = 1.0 / np.sqrt(1.0 + slope * slope)
        centres = np.asarray(spec.centres_mm)
        self._centre_of = centres[np.minimum(index, len(centres) - 1)]
        self._settled_s = spec.settle_s + SETTLE_POLL_S if spec.settle_s > 0 else 0.0
        self._after_decay = math.exp(-(LINK_POLL_S + self._settled_s) / p.relaxation_time_s)
        shape = (num_envs,)
        self.passes = np.full(shape, float(spec.passes_at_start))
        self.y, self.z = np.full(shape, spec.retract_y_mm), np.full(shape, spec.start_z_mm)
        self.depth = np.zeros(shape)
        """Penetration of each cell's roller (mm; the law's ``penetration_mm``)."""
        self.foam = np.zeros(shape)
        self.q = np.zeros(shape)
        drifted = spec.bias_drift_n_per_sqrt_s * math.sqrt(spec.bias_time_s)
        self.bias = drifted * rng.standard_normal(num_envs)  # since the zeroing
        self.noise = np.zeros(shape)
        self.x, self.p_var = np.zeros(shape), np.full(shape, 1.0e8)
        self.step_index = np.zeros(shape, dtype=np.intp)
        self.shift = np.zeros(shape)
        self.wear_reference = np.full(shape, np.nan)
        self.force = np.zeros(shape)
        self.cell_time_s = np.zeros(shape)

    # -- pieces ------------------------------------------------------------------------------
    def _move(self, y1: np.ndarray, z1: np.ndarray, pressing: np.ndarray) -> None:
        """Move every cell to (y1, z1), wait the settle in position; ``pressing``: from above.

        A move longer than ``max_step_mm`` is made of equal moves (the cell's
        ``move_in_steps``), each waited for. The relaxing part decays through
        the moves before the last, the link's command and the arm's start; it
        follows the elastic depth's ramp over the part of the last move in
        contact (all of it for a cell in the foam; from where it meets the
        surface for the ``pressing`` cells, out of the foam before the move),
        then decays through the poll and the settle. A cell already at (y1, z1)
        sends nothing and waits nothing.
        """
        s, p = self.spec, self.spec.sponge
        length = np.hypot(y1 - self.y, z1 - self.z)
        still = length == 0.0
        moves = np.ceil(length * (1.0 / (0.99 * s.max_step_mm)))
        np.maximum(moves, 1.0, out=moves)
        depth = law.penetration_mm(p, self.passes, y1, z1)
        foam = law.elastic_depth_mm(p, np.minimum(depth, p.thickness_mm))
        row = np.rint(length / moves * (1.0 / self._dl)).astype(np.intp)
        in_position_s = self._in_position.take(row, mode="clip")
        touch_s = self._reach_first.take(row, mode="clip")
        if pressing.size:
            touch_s[pressing] = self._touch_s(pressing, y1, z1, moves, row)
        each_s = in_position_s + (LINK_COMMAND_S + LINK_POLL_S)  # a move, seen in position
        q_before = self.q
        if p.relaxation_ratio != 0.0:
            rate = 1.0 / p.relaxation_time_s
            before_s = (moves - 1.0) * each_s + LINK_COMMAND_S + touch_s  # not pressing yet
            ramp_s = np.maximum(in_position_s - touch_s, s.motion.tick_s)
            keep = np.exp(ramp_s * -rate)
            q = self.q * np.exp(before_s * -rate) * keep
            q += (foam - self.foam) * (p.relaxation_time_s / ramp_s) * (1.0 - keep)
            q *= self._after_decay  # the poll and the settle
            q[(foam == 0.0) & (q > 0.0)] = 0.0  # off the foam it recovers
            self.q = q
        self.depth, self.foam, self.y, self.z = depth, foam, y1, z1
        elapsed = moves * each_s + self._settled_s
        if still.any():
            self.q[still] = q_before[still]
            elapsed[still] = 0.0
        self.cell_time_s += elapsed
        self.bias += (s.bias_drift_n_per_sqrt_s * np.sqrt(elapsed)
                      * self.rng.standard_normal(self.n))

    def _touch_s(self, cells: np.ndarray, y1: np.ndarray, z1: np.ndarray, moves: np.ndarray,
                 row: np.ndarray) -> np.ndarray:
        """When the ``cells``' last move, pressing in, meets the surface: s after its command."""
        p, y_end = self.spec.sponge, y1[cells]
        start_y = y_end - (y_end - self.y[cells]) / moves[cells]
        outside = np.maximum(start_y - law.surface_y_mm(p, self.passes[cells], z1[cells]), 0.0)
        fraction = np.clip(outside / np.maximum(start_y - y_end, 1e-12), 0.0, 1.0)
        at = fraction * (len(FRACTIONS) - 1)
        low = np.minimum(at.astype(np.intp), len(FRACTIONS) - 2)
        part = at - low
        base = np.minimum(row[cells], len(self._table) - 1) * len(FRACTIONS) + low
        reached: np.ndarray = self._flat[base] * (1.0 - part) + self._flat[base + 1] * part
        return reached

    def _burst(self, fresh: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Read a burst on every cell through the filter; the filtered forces (N).

        ``fresh``: the cells whose filter starts over (a trial's start).
        The foam relaxes through the burst (q decays); the law is evaluated once,
        at the burst's filter-weighted mean decay, which is exact for a force
        linear in q (the foam in contact), and the samples are that force plus
        the sensor's bias and noise, quantised to counts.
        """
        s, p = self.spec, self.spec.sponge
        normal = law.normal_force_n(p, self.passes, self.depth, self.z, self.q * self._mean_decay)
        true = normal * self._y_share.take(index, mode="clip")  # along the sensor's Y
        noise = self.rng.standard_normal((self.n, s.samples)) @ self._mix
        noise += np.multiply.outer(self.noise, self._carry)
        self.noise = noise[:, -1].copy()
        noise += (true + self.bias)[:, None]
        reading = np.round(noise / s.count_n)
        mean = (reading @ self._weights) * s.count_n
        # the step filter: a move forgets (P += change std^2), a trial's start knows nothing
        r_m = s.filter_variance_n2 * self._burst_factor
        prior = self.p_var + s.move_change_std_n ** 2
        x = self.x
        if fresh.size:
            prior[fresh] = 1.0e8
            x[fresh] = 0.0
        gain = prior / (prior + r_m)
        self.x = x + gain * (mean - x)
        self.p_var = r_m * gain
        return self.x

    # -- the task ----------------------------------------------------------------------------
    def centre_y_mm(self) -> np.ndarray:
        """The map's centre Y (mm) of each cell's next step, its wear shift included."""
        centre: np.ndarray = self._centre_of.take(self.step_index, mode="clip") + self.shift
        return centre

    def reset(self) -> np.ndarray:
        """Retract every cell (a pass), press in at the start; the start forces (N)."""
        force: np.ndarray = self.advance(np.zeros(self.n), np.ones(self.n, dtype=bool))["force_n"]
        return force

    def _retract(self, cells: np.ndarray) -> None:
        """The ``cells`` pull out (a pass if they touched) and travel above the start."""
        s = self.spec
        self.passes[cells] += self.foam[cells] > 0.0
        for state in (self.q, self.foam, self.depth):
            state[cells] = 0.0
        self.y, self.z = self.y.copy(), self.z.copy()  # the last step's are the caller's
        self.y[cells] = s.retract_y_mm
        self.z[cells] = s.start_z_mm
        self.bias[cells] += (s.bias_drift_n_per_sqrt_s * math.sqrt(RESET_TRAVEL_S)
                             * self.rng.standard_normal(cells.size))
        self.cell_time_s[cells] = RESET_TRAVEL_S

    def _track_wear(self, cells: np.ndarray, start_force: np.ndarray) -> None:
        """``SurfaceYOutput.track_wear`` on the ``cells`` (their start forces, N)."""
        k = self.spec.wear_stiffness_n_per_mm
        if k is None:
            return
        reference = self.wear_reference[cells]
        first = np.isnan(reference)
        reference[first] = start_force[first]
        self.wear_reference[cells] = reference
        shift = self.shift[cells] + 0.5 * (start_force - reference) / k
        if self.spec.shift_range_mm is not None:
            shift = np.clip(shift, *self.spec.shift_range_mm)
        later = ~first & np.isfinite(start_force)
        self.shift[cells[later]] = shift[later]

    def advance(self, offset_mm: np.ndarray, resetting: np.ndarray) -> dict[str, Any]:
        """One pass over every cell: the ``resetting`` ones start a trial, the others step.

        A stepping cell moves 5 mm down to its centre + ``offset_mm`` and is
        evaluated (r, failure, the path's end); a resetting one retracts and
        presses in at the start (its ``force_n`` is the start force, r 0). A
        cell whose trial is done must be resetting.
        """
        s = self.spec
        fresh = np.flatnonzero(resetting)
        y1 = self.centre_y_mm() + offset_mm
        index = self.step_index + 1
        if fresh.size:
            self._retract(fresh)
            y1[fresh] = s.start_press_y_mm + self.shift[fresh]
            index[fresh] = 0
        self.step_index = index
        z1 = self._z_of.take(index, mode="clip")
        if s.approach_mm > 0.0:  # stand shallower at the new Z first (a started cell: stay)
            above_y, above_z = y1 + s.approach_mm, z1.copy()
            above_y[fresh], above_z[fresh] = self.y[fresh], self.z[fresh]
            self._move(above_y, above_z, np.flatnonzero(self.foam == 0.0))
        self._move(y1, z1, np.flatnonzero(self.foam == 0.0))
        self.cell_time_s += s.samples * s.sample_period_s  # the burst
        force = self._burst(fresh, index)
        self.force = force
        limit = np.abs(force) > s.max_force_n
        # the task's own ratio, elementwise (abs and / are numpy's on an array)
        r = cast(np.ndarray, s.evaluation.ratio(cast(float, force - s.evaluation.desired_force_n)))
        failed: np.ndarray = r > FAILURE_R
        if limit.any():
            r[limit] = SAFETY_R
            failed |= limit
        if fresh.size:
            self._track_wear(fresh, force[fresh])
            r[fresh] = 0.0
            failed[fresh] = False
        done = failed | (index >= s.steps)
        return {"r": r, "failed": failed, "done": done, "force_n": force, "y_cmd_mm": y1,
                "z_mm": self.z, "limit_hit": limit}
