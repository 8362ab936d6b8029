"""The lag's 1-sigma carries the tick phases the pose reads share across moves."""

from __future__ import annotations

import functools
import math

import numpy as np

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.tools.twin import identify_fit
from forcelearn.tools.twin.identify import Identification, IdentifyPlan, TimedMove

LAG_S = 0.043
LINK_S = 0.073
"""From a move's status poll to its command reaching the controller, s."""
READ_S = 0.0436
"""From a status poll to the pose read after it, s."""
POLL_S = 0.38 / 3
"""A status poll and a pose read: fixed exchange times, as the emulated link's."""
FIRST_S = 0.305 / 3
"""From a move's status poll to the first poll after its command, s."""
STATUS_S = 0.04354
"""A status poll alone (the wait's), s."""


def _moves(grid_s: float, jitter_s: float = 0.0, seed: int = 0,
           speeds: tuple[float, ...] = (math.nan, 20.0, 50.0),
           lengths: tuple[float, ...] = (1.0, 2.0, 3.5, 5.0, 7.0, 9.5)) -> list[TimedMove]:
    """Polled moves of the emulated arm; its tick grid ``grid_s`` off the recorded clock.

    Every exchange takes a fixed time (``jitter_s`` 0): each move's polls and reads come
    at the same times after its command, whatever the command's phase (a dither of up to
    50 ms before each). ``jitter_s``: a host's scheduling, a normal scatter on every
    exchange.
    """
    rng = np.random.default_rng(seed)
    home = Pose(0.0, 0.0, 0.0, (1.0, 0.0, 0.0, 0.0))
    motion = ArmMotion(MotionParams(lag_s=LAG_S), home)
    moves, origin, clock = [], home, 1.0

    def later(t: float) -> float:
        return t + float(rng.normal(0.0, jitter_s)) if jitter_s > 0 else t

    for speed in speeds:
        motion.speed_mm_s = 100.0 if math.isnan(speed) else speed
        for length in lengths:
            for z in (-length, 0.0):
                target = Pose(0.0, 0.0, z, home.quaternion)
                axis = math.copysign(1.0, z - origin.z_mm)

                def progress() -> float:
                    return (motion.pose.z_mm - origin.z_mm) * axis  # noqa: B023

                motion.advance_to(later(clock + READ_S) + grid_s)
                positions, command = [(clock, progress())], clock + POLL_S
                motion.command(target, later(command + LINK_S) + grid_s)
                polls: list[tuple[float, bool | None, bool]] = []
                t, seen = command + FIRST_S - POLL_S, False
                while True:
                    t = later(t + POLL_S)
                    motion.advance_to(t + grid_s)
                    polls.append((t, motion.moving, motion.in_position))
                    motion.advance_to(later(t + READ_S) + grid_s)
                    positions.append((t, progress()))
                    seen = seen or not polls[-1][2]
                    if seen and polls[-1][2] and not polls[-1][1]:
                        break
                moves.append(TimedMove(command, length, speed, polls, positions))
                # the wait: status polls until the dither's settle is over
                polls_waited = max(1, math.ceil(float(rng.uniform(0, 0.05)) / STATUS_S))
                clock, origin = t + 0.2283 + STATUS_S * polls_waited, target
    return moves


@functools.cache
def _locked() -> tuple[list[TimedMove], identify_fit.TimingFit]:
    """The locked moves (the emulated link's) and their fit, shared by the tests."""
    moves = _moves(0.0)
    fit = identify_fit.fit_timing(moves)
    assert fit is not None
    return moves, fit


def test_reads_at_locked_tick_phases_carry_their_shared_error() -> None:
    """Locked reads: the lag's error (-182 us) is mostly the phases', and its sigma says so.

    The fixed exchange times read every move at the same times after its command, and the
    commands come at a few phases of the tick: the tick errors do not average out over the
    moves as the sandwich (clustered by move) takes them to.
    """
    _, fit = _locked()
    error = abs(fit.values["lag_s"] - LAG_S)
    phase = fit.phase_sigmas["lag_s"]
    sandwich = math.sqrt(fit.sigmas["lag_s"] ** 2 - phase**2)
    assert error > sandwich  # beyond what the moves' own scatter explains
    assert phase > sandwich
    assert error < 3 * fit.sigmas["lag_s"]


def test_scattered_exchange_times_leave_the_phases_nothing_to_add() -> None:
    """With 1 ms of jitter on every exchange the phases spread: their share near 0."""
    locked_moves, locked = _locked()
    moves = _moves(0.0, jitter_s=0.001)
    spread = identify_fit.fit_timing(moves)
    assert spread is not None
    assert identify_fit.read_jitter_s(moves) > 0.0005
    assert identify_fit.read_jitter_s(locked_moves) < 1e-9
    assert spread.phase_sigmas["lag_s"] < 0.3 * locked.phase_sigmas["lag_s"]


def test_a_kept_fit_without_the_phases_gets_them_from_its_moves() -> None:
    """An older identification file's kept fit: the phases' share added when read."""
    moves, fit = _locked()
    old = identify_fit.timing_document(fit, identify_fit.BAND_MM)
    sandwich = {n: math.sqrt(max(0.0, s**2 - fit.phase_sigmas.get(n, 0.0) ** 2))
                for n, s in fit.sigmas.items()}
    old = {**old, "sigmas": sandwich}
    del old["phase_sigmas"]
    read = identify_fit.timing_of(Identification(IdentifyPlan(), moves, [], old))
    assert read is not None
    assert read.sigmas["lag_s"] > sandwich["lag_s"]
    assert math.isclose(read.sigmas["lag_s"], fit.sigmas["lag_s"], rel_tol=0.05)
