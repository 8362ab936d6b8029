"""An identification run: a short plan on the cell for what a run's records cannot give.

``forcelearn identify --config site.toml --out DIR`` runs it; ``forcelearn twin RUN_DIR
--identification DIR`` fits with it. A learning run holds its force in band, with moves
of one length and one speed, timed by polls as coarse as the link's exchange (44 ms
on a 9600-baud computer link): the arm's lag, acceleration, speed and start delay trade
off inside those windows, and the foam's relaxation and hysteresis show only as small
differences between like steps. This plan makes them show (docs/twin-fit.md):

===========================  ================================================  ============
part                         what it does                                      determines
===========================  ================================================  ============
free-space hold              ``free_reads`` bursts of ``free_samples`` over    noise, drift
                             ``free_hold_s`` at the retract plane
timed moves                  free-space moves of each length x speed, each     start delay,
                             polled back to back (READ_STATUS / EGM feedback)  acceleration,
                             from the command to in position, after a random   speed, lag
                             dwell (so the polls meet the motion at every
                             phase), ``repeats`` times; on the computer link
                             the tool's pose read after each poll
                             (READ_POSITION): the path in time
press                        steps down at the task's start until the force    stiffness,
                             passes ``press_force_ratio`` x the desired force  contact
step-and-hold                ``hold_steps`` steps in, each raising the force   relaxation
                             by ``hold_force_ratio`` of the desired force,     (ratio and
                             held with bursts at ``hold_s`` (to 6 s: six       time)
                             time constants of a slow foam)
ease off, press in           ``cycles`` of easing off by those steps to the    hysteresis,
                             press's end and in again, each step read at       relaxation
                             ``cycle_hold_s`` (to 1 s) after its own burst     (many steps)
===========================  ================================================  ============

Safe on a real cell: every move goes through the same drivers, limits (step, speed,
workspace) and force guard as a run's; the press stops at the probe's contact rules and
depth limit (``[probe] max_depth_mm``) and the safety force limit, the step-and-hold's steps
end once a reading passes the probe's own limit (``[probe] max_force_ratio`` of the safety
limit: a stiffening foam rises faster than the press's slope), and every move that may
press in goes through the press guard (:mod:`forcelearn.press_guard`), as a run's. The
emulated cell's cell time of the default plan is three to five minutes (185-304 s
on hidden cells of seed 1).

Writes ``DIR/identification.json``: the plan, the polled timing of each move, and the
force records (the run's record format, :mod:`forcelearn.tools.experiments.records`).
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.devices import Pose
from forcelearn.errors import ForcelearnError, SensorSuspect
from forcelearn.press_guard import PressGuard
from forcelearn.records import StepRecord, TrialRecords
from forcelearn.site.config import CellConfig
from forcelearn.tasks.approach import PROBE_APPROACH_ADVICE, FineApproach
from forcelearn.tools.experiments.records import step_from_json, step_to_json
from forcelearn.tools.experiments.run_recorder import TrialRecorder

log = logging.getLogger(__name__)

FILE = "identification.json"
FORMAT = 1
IDENTIFY_TRIAL = -2
"""Trial number of the identification's force records (the probe's is -1)."""
POLL_LIMIT = 2000
"""Most polls of one timed move (a move that never reports in position is an error)."""
FAST_WAIT_S = 0.1
"""A hold's wait shorter than this (s) is one status poll, not a dwell (:func:`_hold`)."""
UNSEEN_S = 1.0
"""A move whose motion no poll saw within this time (s) ends there (too short to see)."""
READ_S = 0.2
"""Cell time the pose reads add to a timed move, s (the computer link at 9600 baud: 94 s ->
125 s over the 154 timed moves of hidden cell 1 of seed 1)."""
MIN_REACH = 0.25
"""A step-and-hold step the press guard would cut to less than this share is not made."""


class IdentificationError(ForcelearnError):
    """The identification could not finish its plan (the robot has been stopped)."""


@dataclass(frozen=True)
class IdentifyPlan:
    """The identification's plan; lengths in mm, speeds in mm/s, times in s, forces as ratios."""

    lengths_mm: tuple[float, ...] = (1.0, 1.5, 2.0, 2.75, 3.5, 4.25, 5.0, 6.0, 7.0, 8.25, 9.5)
    speeds_mm_s: tuple[float, ...] = (10.0, 20.0, 35.0, 50.0, 75.0, 100.0)
    repeats: int = 1
    """Passes over the lengths x speeds. Many distinct (length, speed) pairs, rather than
    repeats of a few: the polls are timed from the command, so a repeated move meets them at
    the same phase; distinct durations spread the phases over the poll period."""
    read_positions: bool = True
    """Read the tool's pose after each status poll of a timed move (the computer link's
    READ_POSITION; a robot whose polls carry no moving flag, EGM, reads none): the poses
    during the motion time the acceleration and the lag to the interpolation tick."""
    dither_s: float = 0.05
    """Longest random dwell before a timed move (spreads the polls' phase)."""
    free_reads: int = 10
    free_samples: int = 32
    free_hold_s: float = 20.0
    press_force_ratio: float = 0.5
    """The press goes on until the force passes this share of the task's desired force."""
    hold_s: tuple[float, ...] = (0.04, 0.08, 0.12, 0.16, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8,
                                 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0)
    """Times after each step-and-hold step at which the held press is read (and at once), s:
    to 6 time constants of the slowest foam the study draws (1 s), dense where a fast one
    (0.2 s) relaxes; waits under ``FAST_WAIT_S`` are single polls."""
    hold_samples: int = 48
    """Samples of each hold's burst (48 ms at the JR3 adapter's 1 kHz: the holds are timed,
    so a longer burst reads more of the relaxation and waits less on polls)."""
    hold_steps: int = 6
    """Step-and-hold steps: each steps in and holds (the first holds at the press's end)."""
    hold_force_ratio: float = 0.3
    """Each step's depth: this share of the desired force at the press's unrelaxed slope."""
    cycles: int = 2
    cycle_mm: float = 3.0
    """The longest step-and-hold step, mm (the cycles ease off by those steps and back)."""
    cycle_hold_s: tuple[float, ...] = (0.04, 0.08, 0.12, 0.16, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6,
                                       0.8, 1.0)
    """Times after each cycle's step at which it is read (after its own burst), s: each
    step in or out is a relaxation of its own (a fast foam's whole, a slow one's start).
    A step takes 0.2-0.6 s to come in position on the hidden cells (the lag), so a foam
    of 0.2-0.35 s has relaxed most of the way when the first burst comes: each step shows
    only the tail, and the six holds alone left the ratio of hidden cells 18, 25, 30 of
    seed 1 (0.08-0.22) 27-42 % off; the cycles' 20 steps are many more tails."""
    hold_settle_s: float = 0.0
    """The dwell in position before a step-and-hold or cycle step's first burst, s (the
    cell's ``settle_s``, 0.05 s, elsewhere: two 44 ms polls): a 0.25 s foam relaxes by a
    third during that dwell, and the move itself takes 0.2-0.6 s on the hidden cells."""
    step_samples: int = 16
    restore_speed_mm_s: float = 100.0
    """The speed the arm is left at when the robot config names none (the emulator's)."""

    def __post_init__(self) -> None:
        if not (self.lengths_mm and self.speeds_mm_s and self.repeats >= 1):
            raise ValueError("an identification plan needs lengths, speeds and repeats >= 1")
        if min(self.lengths_mm) <= 0 or min(self.speeds_mm_s) <= 0:
            raise ValueError("identification lengths and speeds must be > 0")
        if not 0 < self.press_force_ratio < 1:
            raise ValueError("press_force_ratio must be in (0, 1): the press stays under the "
                             "task's desired force")

    def cell_time_s(self) -> float:
        """A rough cell time of the plan (moves at their speeds, dwells, holds), s."""
        per_move = 0.3 + (READ_S if self.read_positions else 0.0)
        moves = sum(2 * (length / speed + per_move) for length in self.lengths_mm
                    for speed in self.speeds_mm_s) * self.repeats
        cycle_hold = max(self.cycle_hold_s, default=0.0)
        return (self.free_hold_s + moves + self.hold_steps * (max(self.hold_s) + 0.5) + 30.0
                + self.cycles * 2 * self.hold_steps * (0.5 + cycle_hold))


@dataclass(frozen=True)
class TimedMove:
    """One polled free-space move: command time, length, speed and the polls, s and mm."""

    command_s: float
    length_mm: float
    speed_mm_s: float
    """The speed set for the move; NaN: the robot's own (what a run's moves use)."""
    polls: list[tuple[float, bool | None, bool]]
    """(controller time s, moving (None: not reported), in position) of each poll."""
    positions: list[tuple[float, float]] = field(default_factory=list)
    """The tool's pose read after each status poll (READ_POSITION, the computer link):
    (the status poll's controller time s, the tool's progress along the move from its start
    target mm); the first is read before the command (its time the wait's end), the tool
    still settling on the previous target. Empty: not read (EGM's 4 ms polls, an old file)."""


@dataclass(frozen=True)
class Identification:
    """What an identification run recorded."""

    plan: IdentifyPlan
    moves: list[TimedMove]
    records: list[TrialRecords]
    timing: dict[str, Any] | None = None
    """The arm's timing fitted to ``moves`` as the file keeps it (``band_mm``, ``values``,
    ``sigmas``, ``rms_s``, ``moves``; :func:`~.identify_fit.timing_of`); None: not fitted."""


def _poll(robot: Any) -> tuple[float, bool | None, bool]:
    """One status poll of the computer link (time_s, moving) or of EGM (controller time)."""
    status = robot.read_status()
    if hasattr(status, "moving"):
        return float(status.time_s), bool(status.moving), bool(status.in_position)
    return float(status.controller_time_s), None, bool(status.in_position)


def _progress_mm(pose: Pose, origin: Pose, target: Pose) -> float:
    """How far ``pose`` is along the straight move from ``origin`` to ``target``, mm."""
    axis = np.subtract(target.position_mm, origin.position_mm)
    return float(np.dot(np.subtract(pose.position_mm, origin.position_mm), axis)
                 / max(float(np.linalg.norm(axis)), 1e-12))


def _timed_move(cell: Any, origin: Pose, target: Pose, length: float, speed: float,
                read_positions: bool) -> TimedMove:
    """A move from ``origin`` (the last target) to ``target``, polled until in position.

    ``read_positions``: the tool's pose is read before the command and after every status
    poll (:attr:`TimedMove.positions`): a pose read during the motion times it to the
    controller's interpolation tick, where the in-position poll's window is a whole
    exchange wide (44 ms of status polls at 9600 baud). The command goes right after the
    status poll that times it, as without the reads.
    """
    robot = cell.robot
    positions = []
    if read_positions:  # where the tool settles before the command, at the wait's end
        positions.append((float(cell.time_s), _progress_mm(robot.read_pose(), origin, target)))
    command_s = _poll(robot)[0]
    robot.move_to(target)
    polls, seen = [], False
    for _ in range(POLL_LIMIT):
        poll = _poll(robot)
        polls.append(poll)
        if read_positions:
            positions.append((poll[0], _progress_mm(robot.read_pose(), origin, target)))
        seen = seen or poll[1] is True or not poll[2]
        if poll[2] and poll[1] is not True and (seen or poll[0] - command_s > UNSEEN_S):
            break  # in position after the motion (or a move too short to be seen)
    else:
        robot.stop()
        raise IdentificationError(f"a {length:g} mm move at {speed:g} mm/s did not report in "
                           f"position within {POLL_LIMIT} polls; the robot was stopped")
    cell.sync()  # the cell's pose and time follow the robot's
    return TimedMove(command_s, length, speed, polls, positions)


def _timing_part(cell: Any, config: CellConfig, plan: IdentifyPlan,
                 rng: np.random.Generator) -> list[TimedMove]:
    """The free-space moves, polled: each length x speed, out and back, ``repeats`` times."""
    robot = cell.robot
    if not hasattr(robot, "read_status") or not hasattr(robot, "set_speed"):
        return []  # a robot kind without status polls or speeds: the records' timing only
    home = cell.pose
    limit = getattr(getattr(config.robot, "limits", None), "max_speed_mm_s", math.inf)
    reads = plan.read_positions and hasattr(robot, "read_pose") and _poll(robot)[1] is not None
    moves = []
    # the robot's own speed (NaN: what a run's moves use) first, then each set speed
    speeds = [math.nan] * plan.repeats + [v for _ in range(plan.repeats)
                                          for v in plan.speeds_mm_s if v <= limit]
    for speed in speeds:
        if not math.isnan(speed):
            robot.set_speed(speed)
        for length in plan.lengths_mm:
            if length > config.safety.max_step_mm:
                continue
            origin = home
            for z in (home.z_mm - length, home.z_mm):
                cell.time_s = robot.wait_in_position(cell.move_timeout_s,
                                                     float(rng.uniform(0, plan.dither_s)))
                target = Pose(home.x_mm, home.y_mm, z, home.quaternion)
                moves.append(_timed_move(cell, origin, target, length, speed, reads))
                origin = target
    robot.set_speed(float(getattr(config.robot, "speed_mm_s", plan.restore_speed_mm_s)))
    return moves


def _guard(cell: Any, config: CellConfig) -> PressGuard:
    """The cell's press guard (a new one as a run's when it has none): every press is cut by it."""
    if cell.press_guard is None:
        cell.press_guard = PressGuard(config.safety.max_force_n,
                                      config.task.press_stiffness_n_per_mm,
                                      cell.force_filter.measurement_variance_n2 ** 0.5)
    guard: PressGuard = cell.press_guard
    return guard


def _press_to(cell: Any, config: CellConfig, pose: Pose) -> None:
    """A move that may press in, through the press guard (as a run's and the probe's)."""
    cell.move_in_steps(pose, config.safety.max_step_mm, guard_force=True)


def _hold(cell: Any, plan: IdentifyPlan, stage: str, index: int, at_once: bool = True,
          times: tuple[float, ...] | None = None) -> None:
    """A burst at once and at ``times`` (``plan.hold_s``) after the last move (fast-polled).

    ``at_once`` False: the move's burst was read already (a second burst read at once
    would carry the same time stamp, the last wait's end, as the one before it).

    A wait shorter than ``FAST_WAIT_S`` is one status poll (the link's exchange, 44 ms on a
    9600-baud computer link): a wait with a dwell polls until the dwell passed, at least two
    polls, and bursts meant for 0.02, 0.05 and 0.1 s all read at 0.09 s.
    """
    times = plan.hold_s if times is None else times
    held = cell.time_s
    if at_once:
        cell.stage = (stage, index * (len(times) + 1))
        cell.measure_force_n(plan.hold_samples)
    for k, after in enumerate(times, start=1):
        wait = held + after - cell.time_s
        if wait <= 0:
            continue  # the poll before already passed it
        cell.time_s = cell.robot.wait_in_position(cell.move_timeout_s,
                                                  0.0 if wait < FAST_WAIT_S else wait)
        cell.stage = (stage, index * (len(times) + 1) + k)
        cell.measure_force_n(plan.hold_samples)


def _force_part(cell: Any, config: CellConfig, plan: IdentifyPlan) -> None:
    """Free-space hold, press, step-and-hold, press in and ease off (records via the cell).

    The press steps down in ``[probe] approach_step_mm``, refined at its first contact on a
    stiff part (:mod:`forcelearn.tasks.approach`: on 8 N/mm at 5 N one 1 mm step passed the
    whole press, which then measured a rise of 0 and the step-and-hold took no step). Where
    even the finest step passes the press (18.6 N/mm from a 2.2 N contact to 2.53 N: hidden
    cell 24 of seed 4 was refused), the press ends deeper, up to the task's desired force,
    to read the part :data:`~forcelearn.tasks.approach.READINGS` times.
    Every move that may press in goes through the press guard
    (:mod:`forcelearn.press_guard`): on a stiff part a step is cut where the force it is
    predicted to meet would pass ``[safety] max_force_n`` (hidden cell 17 of seed 1 read
    22.4 N over its 20.9 N limit in the unguarded press-in cycles).
    """
    home = cell.pose
    guard = _guard(cell, config)
    cell.stage = ("identify-free", 0)
    for k in range(plan.free_reads):
        cell.time_s = cell.robot.wait_in_position(cell.move_timeout_s,
                                                  plan.free_hold_s / plan.free_reads)
        cell.stage = ("identify-free", k)
        cell.measure_force_n(plan.free_samples)
    probe = config.probe
    target_n = plan.press_force_ratio * config.task.desired_force_n
    approach = FineApproach(  # refined on a stiff part; widened to the desired force there
        probe.approach_step_mm, probe.contact_force_n, target_n - probe.contact_force_n,
        PROBE_APPROACH_ADVICE, "raise [task] desired_force_n or the plan's press_force_ratio, "
        "or lower [probe] contact_force_n",
        widest_span_n=config.task.desired_force_n - probe.contact_force_n)
    y, index, force = home.y_mm, 0, 0.0
    free = (y, force)  # the last reading in free space (y mm, N)
    bottom = config.task.start_mm[1] - probe.max_depth_mm  # until contact is found
    contact: tuple[float, float] | None = None  # the first reading in contact (y mm, N)
    span_n = approach.span_n
    while force < target_n:
        y -= approach.step_mm
        if y < bottom:
            raise IdentificationError(
                f"the press read {force:.2f} N at most, under {target_n:.2f} N, within "
                "[probe] max_depth_mm of contact: it pressed no further (check the task's "
                "start pose and the probe's settings)")
        index += 1
        cell.stage = ("identify-press", index)
        _press_to(cell, config, Pose(home.x_mm, y, home.z_mm, home.quaternion))
        y = cell.pose.y_mm  # where the guard let it go
        force = cell.measure_force_n(plan.step_samples)
        if force > probe.contact_force_n and contact is None:
            if approach.again(force, free[1], free[0] - y, " of the identification's press"):
                y, force = free  # back out to the free reading; step in again, finer
                _press_to(cell, config, Pose(home.x_mm, y, home.z_mm, home.quaternion))
                continue
            contact = (y, force)
            bottom = max(bottom, y - probe.max_depth_mm)  # at most max_depth_mm deeper
            if approach.span_n != span_n:  # widened: a stiff part with a small force
                target_n = probe.contact_force_n + approach.span_n
        elif contact is None:
            free = (y, force)
    # step-and-hold: step in ``hold_steps`` times, each by the depth the press took from
    # contact to ``target_n`` scaled to ``hold_force_ratio`` of the desired force, and hold
    # (relaxation: the force falls towards its relaxed value with the foam's time constant)
    assert contact is not None  # the press ended above target_n > contact_force_n
    rise = max((force - contact[1]) / max(contact[0] - y, 1e-3), 1e-3)  # N/mm, unrelaxed
    hold_mm = min(plan.hold_force_ratio * config.task.desired_force_n / rise, plan.cycle_mm)
    # each step's first burst at once in position: a fast foam relaxes during a dwell
    settle, cell.settle_s = cell.settle_s, plan.hold_settle_s
    try:
        if plan.hold_steps:  # the press's last burst is the hold's first
            _hold(cell, plan, "identify-hold", 0, at_once=False)
        depths = [y]  # where each hold was
        for k in range(1, plan.hold_steps):
            depth = y - hold_mm
            if depth < bottom:
                break
            target = Pose(home.x_mm, depth, home.z_mm, home.quaternion)
            reach = guard.reach(cell.pose.position_mm, target.position_mm)
            if reach < MIN_REACH:
                break  # the press guard allows too little of the step: the force limit is near
            if reach < 1.0:  # as far as the guard allows: it takes the site's stiffness until
                # two readings rise by 3 sigma (a soft, noisy part's 1 mm approach steps never
                # do, and the whole step-and-hold was cut on hidden cells 2, 3, 18 of seed 1)
                target = Pose(home.x_mm, y - reach * hold_mm, home.z_mm, home.quaternion)
            cell.stage = ("identify-step", k)
            # a stiffening or relaxing foam rises faster than the press's slope: the step ends
            # once a cut of the guard reads past the probe's own limit, or where the guard
            # allows no more (hidden cell 30 of seed 8, 2 N/mm stiffening: the fifth step's
            # cut read 56.8 N of the 63.4 N limit, the guard refused the rest, and the refusal
            # ended the identification); the hold is made there and the steps end
            stopped = cell.press_in_steps(target, config.safety.max_step_mm,
                                          probe.limit_n(config.safety.max_force_n))
            y = cell.pose.y_mm
            depths.append(y)
            _hold(cell, plan, "identify-hold", k)
            if stopped:
                break
        # ease off through the holds' depths to the press's end and back in (hysteresis)
        visits = [*depths[-2::-1], *depths[1:]] if len(depths) > 1 else []
        for cycle in range(plan.cycles):
            for j, depth in enumerate(visits):
                cell.stage = (f"identify-cycle{cycle}", j)
                _press_to(cell, config, Pose(home.x_mm, depth, home.z_mm, home.quaternion))
                cell.measure_force_n(plan.step_samples)
                _hold(cell, plan, f"identify-cycle{cycle}-hold", j, at_once=False,
                      times=plan.cycle_hold_s)
    finally:
        cell.settle_s = settle
    cell.stage = ("retreat", 0)
    _retreat(cell, config, home)


def _retreat(cell: Any, config: CellConfig, home: Pose) -> None:
    """Back from the press to ``home`` above the part, the zero taken again if it walked.

    Guarded like every move; a reading of a pull on the way (:class:`SensorSuspect`: the
    sensor's zero walked during the minutes of pressing) does not lose what was read: the
    tool goes on away from the part (the part pushes no more once the tool leaves it) and
    the sensor is zeroed in free space there. Hidden cell 24 of seed 11 (a 0.07 N sensor
    whose zero walks) read -0.82 N on its way back, and the whole identification was lost.
    """
    try:
        cell.move_in_steps(home, config.safety.max_step_mm, guard_force=True)
    except SensorSuspect as exc:
        log.warning("identification: %s; retreating to the free space above and zeroing there",
                    exc)
        cell.move_in_steps(home, config.safety.max_step_mm, guard_force=False)
        cell.tare(config.task.tare_max_reading_n)


def run_identification(config: CellConfig, plan: IdentifyPlan | None = None,
                       seed: int = 0) -> Identification:
    """Run the plan on the cell ``config`` names (emulated or real) and return what it read."""
    from forcelearn.site import CellSession

    plan = plan or IdentifyPlan()
    rng = np.random.default_rng(seed)
    task = config.task
    with CellSession(config, seed=seed) as session:
        cell = session.cell
        assert cell is not None  # an open session has its cell
        recorder = TrialRecorder(cell)
        cell.recorder = recorder
        cell.sync()
        x0, _, z0 = task.start_mm
        above = Pose(x0, task.retract_y_mm, z0, task.orientation)
        cell.stage = ("approach", 0)
        cell.move_in_steps(above, config.safety.max_step_mm, guard_force=True)
        cell.tare(task.tare_max_reading_n)
        recorder.discard()
        moves = _timing_part(cell, config, plan, rng)
        _force_part(cell, config, plan)
        records = [recorder.take(IDENTIFY_TRIAL)]
        cell.recorder = None
    return Identification(plan, moves, records)


def write_identification(result: Identification, out: Path) -> Path:
    """Write ``out/identification.json``; return its path."""
    out.mkdir(parents=True, exist_ok=True)
    document = {
        "format": FORMAT,
        "plan": asdict(result.plan),
        "moves": [asdict(move) for move in result.moves],
        "records": [{"trial": t.trial, "steps": [step_to_json(s) for s in t.steps]}
                    for t in result.records],
    }
    if result.timing is not None:
        document["timing"] = result.timing
    path = out / FILE
    path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return path


def read_identification(folder: Path) -> Identification:
    """Read ``folder/identification.json`` (ValueError: not an identification's)."""
    path = folder / FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: run forcelearn identify --out {folder}")
    document = json.loads(path.read_text(encoding="utf-8"))
    if document.get("format") != FORMAT:
        raise ValueError(f"{path}: format {document.get('format')!r}, expected {FORMAT}")
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v
                              for k, v in document["plan"].items()}
    plan = IdentifyPlan(**fields)
    moves = [TimedMove(m["command_s"], m["length_mm"], m["speed_mm_s"],
                       [(float(t), None if mv is None else bool(mv), bool(ip))
                        for t, mv, ip in m["polls"]],
                       [(float(t), float(p)) for t, p in m.get("positions", [])])
             for m in document["moves"]]
    records = [TrialRecords(t["trial"], [step_from_json(s) for s in t["steps"]])
               for t in document["records"]]
    steps: list[StepRecord] = [s for t in records for s in t.steps]
    if not steps and not moves:
        raise ValueError(f"{path} holds no identification data")
    return Identification(plan, moves, records, document.get("timing"))
