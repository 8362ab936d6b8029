"""The driver's side of an EGM session as pure state: datagrams in, the next reply out (no I/O).

:class:`Guidance` is fed every datagram with its source address
(:meth:`Guidance.on_datagram`) and builds the EgmSensor answer
(:meth:`Guidance.reply`). Nothing a datagram holds raises here: each one is
used, or counted and ignored (:class:`.stats.EgmStats`). Rules, in the order
they are applied:

* **Pairing**: only the controller's datagrams are used: from
  ``controller_host`` (and ``controller_port``) when configured, and from the
  source of the first datagram that starts a session, pinned for the
  driver's life. Any other sender counts as ``foreign_datagrams``.
* A datagram that does not decode (or lacks a finite Cartesian feedback
  pose) counts as ``bad_datagrams``; one that proves the other RobotWare
  egm.proto as ``wrong_version`` (before a session, the refusal names
  ``robot.version``).
* The first datagram, and a later one with ``seqno == 0``, starts a
  **session**, but only when its feedback pose is finite, unit and inside the
  client workspace (else ``refused_sessions``, and :attr:`Guidance.refusal`
  says why; the running session, if any, goes on). A seqno 0 whose header
  ``tm`` is not newer than the latest one is a **replay** (``replays``)
  unless the controller has been silent for ``watchdog_s``.
  The new session's target is the feedback pose; the planned pose is *not*
  reset: it ramps from where it was (restart or replay, no jump).
* A datagram is **fresh** (and answered) only if its seqno is newer than the
  latest one (mod 2**32) by at most ``max_seqno_ahead`` (one watchdog of
  cycles; more is ``seqno_jumps``) and its header ``tm`` is not older (else a
  ``replays``: a datagram of an earlier session). Skipped seqnos count as ``missed``; an
  equal seqno is a ``duplicate``; an older one is ``out_of_order``; none of
  these is answered nor overwrites newer feedback.
* A stream held back by a forged datagram is taken up again: after
  ``RESYNC_AFTER`` refused datagrams with consecutive seqnos and rising tm,
  and as many periods without a fresh one (``resyncs``; the target is kept).
* Every reply moves the planned pose toward the target by at most
  ``speed_mm_s`` x ``sample_period_s`` (and ``TURN_DEG_S`` x period in
  orientation: :func:`.ramp.step_toward`), then checks it against the
  workspace: the controller is never asked for a jump nor for a pose outside
  the box, the first reply included.
* In position: the planned pose has reached the target, and the controller's
  feedback and its own planned pose are within ``in_position_mm`` /
  ``in_position_deg`` of it.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, replace
from typing import Any

from forcelearn.devices import Pose
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.drivers.egm.ramp import TURN_DEG_S, angle_deg, distance_mm, finite_pose, step_toward
from forcelearn.drivers.egm.stats import EgmStats
from forcelearn.drivers.egm.stopped import require_running
from forcelearn.drivers.egm.targets import FEEDBACK_NORM_TOLERANCE, unsafe_reason
from forcelearn.errors import (
    EgmVersionMismatch,
    ForcelearnError,
    ProtocolError,
    SafetyStop,
)
from forcelearn.protocols.egm import carried, codec

__all__ = [
    "RESYNC_AFTER", "TURN_DEG_S", "EgmStats", "Guidance", "Source", "angle_deg", "distance_mm",
    "step_toward",
]

log = logging.getLogger(__name__)

_SEQNO_MOD = 1 << 32
RESYNC_AFTER = 3
"""Refused datagrams in a row (consecutive seqnos) and periods without a fresh one before
the driver takes that chain up as the controller's stream (:meth:`Guidance._resyncs`)."""


def _older(tm_ms: int, than_ms: int) -> bool:
    """Whether header tm ``tm_ms`` is before ``than_ms`` (ms, mod 2**32, half a range back)."""
    return 0 < (than_ms - tm_ms) % _SEQNO_MOD <= _SEQNO_MOD // 2


Source = Any
"""A datagram's source address, as ``recvfrom`` gives it: (host, port) over UDP."""


class Guidance:
    """What the driver knows of the controller and what it asks of it. Not thread-safe."""

    def __init__(self, config: EgmConfig) -> None:
        self.config = config
        self.latest: codec.RobotMessage | None = None
        self._latest_raw: carried.Datagram | None = None
        self.target: Pose | None = None
        """Last accepted target (the step limit is measured from it)."""
        self.planned: Pose | None = None
        """Planned pose of the last reply (ramps toward ``target``)."""
        self.speed_mm_s = config.speed_mm_s
        self.session = 0
        self._counts = asdict(EgmStats())  # a dict: counting is per datagram, hot
        self.controller: Source | None = None
        """The paired controller's address, pinned by the first session start."""
        self.refusal: ForcelearnError | None = None
        """Why the latest refused datagram could not start a session (None once one starts)."""
        self._next_seqno = 0
        self.origin_us: int | None = None
        """feedBack.time (µs since 1970) of the first message that had one: controller time 0."""
        self._before_restart: codec.RobotMessage | None = None
        self._chain: tuple[codec.RobotMessage, int] | None = None  # refused, consecutive
        self._latest_s: float | None = None  # host time of the latest fresh datagram
        self._sent: Pose | None = None  # the latest planned pose checked and sent
        self._in_position: tuple[tuple[Pose | None, ...], bool] | None = None  # inputs, result

    # -- input ------------------------------------------------------------------------------

    def finish_latest(self) -> None:
        """Fill in what the latest in-process EgmRobot left out (``Carried.pending``).

        The emulated lockstep controller leaves the measured force out of the
        messages a wait reads cycle after cycle; the message the wait ends on
        is finished here, before the cell moves on (over UDP: nothing to do).
        """
        raw = self._latest_raw
        if type(raw) is carried.Carried and raw.pending is not None:
            raw.finish()
            message = raw.message
            self.latest = (message if isinstance(message, codec.RobotMessage)
                           else codec.decode_robot(bytes(raw), self.config.version))

    @property
    def latest_raw(self) -> bytes | None:
        """The datagram ``latest`` was read from (what a checkpoint keeps)."""
        raw = self._latest_raw
        return None if raw is None else bytes(raw)

    def on_datagram(
        self, data: carried.Datagram, source: Source = None, now_s: float | None = None
    ) -> bool:
        """Take one datagram from ``source``; True if it is fresh and must be answered.

        Never raises for what the datagram holds: a datagram that cannot be
        used is counted (:class:`EgmStats`) and ignored. ``now_s`` (host
        monotonic seconds) lets a seqno 0 restart a session after the
        controller was silent for ``watchdog_s``; None: never silent.
        """
        self._counts["received"] += 1  # (not _count: every datagram, hot)
        if not self._from_controller(source):
            self._count(foreign_datagrams=1)
            return False
        message = carried.received_robot(data, self.config.version)
        if message is None:
            message = self._decode(bytes(data))
            if message is None:
                return False
        latest = self.latest
        if latest is None or (message.seqno == 0 and latest.seqno != 0):
            if latest is not None and not self._newer_session(message, latest, now_s):
                if self._resyncs(message, now_s):
                    return self._fresh(data, now_s)
                self._count(replays=1)
                return False
            if not self._start_session(message, source):
                return False
            self._before_restart = latest
            return self._fresh(data, now_s)
        ahead = (message.seqno - latest.seqno) % _SEQNO_MOD
        if ahead == 0:
            counter = "duplicates"
        elif ahead >= _SEQNO_MOD // 2:
            counter = "out_of_order"
        elif ahead > self.config.max_seqno_ahead:
            counter = "seqno_jumps"
        elif _older(message.tm_ms, latest.tm_ms):
            counter = "replays"  # a newer seqno with an older tm: an earlier session's datagram
        else:
            counter = ""
        if counter and self._resumes(message):
            self._count(resumed_streams=1)
            return self._fresh(data, now_s)
        if counter and counter != "duplicates" and self._resyncs(message, now_s):
            return self._fresh(data, now_s)
        if counter:
            self._count(**{counter: 1})
            return False
        if not finite_pose(message.feedback):
            self._count(bad_datagrams=1)  # no feedback, or not finite: nothing to read
            return False
        if message.seqno != 0:
            self._before_restart = None  # the new session is confirmed by its own stream
        self._counts["missed"] += ahead - 1
        self.latest = message
        return self._fresh(data, now_s)

    def _decode(self, data: bytes) -> codec.RobotMessage | None:
        """The EgmRobot in ``data``; None (counted) if it proves the other version or is broken."""
        try:
            codec.check_version(data, self.config.version)
        except EgmVersionMismatch as exc:
            self._count(wrong_version=1)
            if self.latest is None:
                self.refusal = exc
            return None
        except ProtocolError:
            self._count(bad_datagrams=1)
            return None
        try:
            return codec.decode_robot(data, self.config.version)
        except ProtocolError:
            self._count(bad_datagrams=1)
            return None

    def _resumes(self, message: codec.RobotMessage) -> bool:
        """Whether ``message`` continues the stream a seqno 0 just interrupted; if so, take it.

        Before the new session's seqno 1 arrives, a datagram 1..max_seqno_ahead
        after the previous session's latest shows the seqno 0 was not the
        controller's (it goes on counting): its stream is taken up again and the
        target held at its feedback. A replay cannot do this (its seqno is not
        newer than what was seen).
        """
        before = self._before_restart
        if (before is None or not finite_pose(message.feedback)
                or _older(message.tm_ms, before.tm_ms)):
            return False
        ahead = (message.seqno - before.seqno) % _SEQNO_MOD
        if not 0 < ahead <= self.config.max_seqno_ahead:
            return False
        self._before_restart = None
        self.latest = message
        self.hold()
        return True

    def _resyncs(self, message: codec.RobotMessage, now_s: float | None) -> bool:
        """Whether the stream is stuck and ``message`` ends a chain to take up; if so, take it.

        A forged datagram far ahead (seqno within the bound, or tm) would make
        every later datagram of the real controller look old. When no fresh
        datagram came for :data:`RESYNC_AFTER` sample periods while
        :data:`RESYNC_AFTER` refused ones came with consecutive seqnos and
        rising tm, that chain is the controller's stream: the driver takes it
        up (``resyncs``; its feedback must be safe to adopt), target kept. While
        the controller's stream is fresh, no chain is taken (a replayed chain
        cannot take over a live stream).
        """
        chain = self._chain
        linked = (
            chain is not None
            and (message.seqno - chain[0].seqno) % _SEQNO_MOD == 1
            and not _older(message.tm_ms, chain[0].tm_ms)
        )
        length = chain[1] + 1 if linked and chain is not None else 1
        self._chain = (message, length)
        stuck = (
            now_s is not None
            and self._latest_s is not None
            and now_s - self._latest_s > RESYNC_AFTER * self.config.sample_period_s
        )
        safe = unsafe_reason(message.feedback, self.config.limits, FEEDBACK_NORM_TOLERANCE)
        if length < RESYNC_AFTER or not stuck or safe is not None:
            return False
        self._chain = None
        self._before_restart = None
        self.latest = message  # the target stays: it was checked when it was set
        self._count(resyncs=1)
        log.warning("EGM stream taken up again at seqno %d after a forged or stale datagram",
                    message.seqno)
        return True

    def _fresh(self, data: carried.Datagram, now_s: float | None) -> bool:
        """Keep ``data`` as the latest (``self.latest`` is its message); True: answer it."""
        latest = self.latest
        if self.origin_us is None and latest is not None and latest.time_us is not None:
            self.origin_us = latest.time_us  # only a datagram taken sets the controller's time 0
        self._chain = None
        self.refusal = None  # the controller's stream goes on: an earlier refusal is moot
        self._latest_raw = data
        self._latest_s = now_s
        return True

    def _from_controller(self, source: Source) -> bool:
        """Whether ``source`` may be the paired controller (configured, then pinned)."""
        if self.controller is not None:
            return bool(source == self.controller)
        host = self.config.controller_host
        if host is None:
            return True
        try:
            from_host, from_port = source[0], source[1]
        except (TypeError, IndexError, KeyError):
            return False
        port = self.config.controller_port
        return bool(from_host == host and (port is None or from_port == port))

    def _newer_session(
        self, message: codec.RobotMessage, latest: codec.RobotMessage, now_s: float | None
    ) -> bool:
        """Whether a seqno 0 is a restart: its tm is newer, or the controller fell silent."""
        newer = 0 < (message.tm_ms - latest.tm_ms) % _SEQNO_MOD < _SEQNO_MOD // 2
        silent = (
            now_s is not None
            and self._latest_s is not None
            and now_s - self._latest_s > self.config.watchdog_s
        )
        return newer or silent

    def _start_session(self, message: codec.RobotMessage, source: Source) -> bool:
        """Adopt ``message`` as a new session's start if its feedback is safe; else refuse it."""
        reason = unsafe_reason(message.feedback, self.config.limits, FEEDBACK_NORM_TOLERANCE)
        if reason is not None:
            self._count(refused_sessions=1)
            if message.feedback is None:
                self.refusal = ProtocolError(
                    "EgmRobot without feedBack.cartesian: run EGMSetupUC with \\Pose "
                    "(rapid/ForcelearnEGM.modx), not \\Joint"
                )
            else:
                self.refusal = SafetyStop(
                    f"refused to start an EGM session: the controller's feedback is {reason}; "
                    "the robot is held (nothing answered): jog it inside the workspace box, "
                    "then restart the RAPID program"
                )
            return False
        assert message.feedback is not None
        if self.controller is None:
            self.controller = source
            log.info("EGM controller paired: %s (held for this driver's life)", source)
        self.latest = message
        self.target = message.feedback
        if self.planned is None:
            self.planned = message.feedback  # first session: the ramp starts where the robot is
        self.refusal = None
        self.session += 1
        self._next_seqno = 0
        self._count(sessions=1)
        return True

    @property
    def stats(self) -> EgmStats:
        """The counters as they are now (a snapshot)."""
        return EgmStats(**self._counts)

    def _count(self, **increments: int) -> None:
        counts = self._counts
        for name, value in increments.items():
            counts[name] += value

    # -- output -----------------------------------------------------------------------------

    def reply(self) -> bytes:
        """Return the EgmSensor answering the latest message, one ramp step nearer the target.

        Raises ``SafetyStop`` (nothing sent, the planned pose kept) if the
        stepped pose is not finite or leaves the workspace, which the checks
        on targets and feedback should make impossible.
        """
        return bytes(self.reply_carried())

    def reply_carried(self) -> carried.Carried:
        """:meth:`reply` not encoded yet (an in-process controller reads its message as it is)."""
        if self.latest is None or self.planned is None or self.target is None:
            raise RuntimeError("no EGM session yet: nothing to answer")
        planned = self.planned
        if not (planned is self.target and planned is self._sent):  # else at rest: sent as is
            period = self.config.sample_period_s
            planned = step_toward(
                planned, self.target, self.speed_mm_s * period, TURN_DEG_S * period
            )
            reason = unsafe_reason(planned, self.config.limits, FEEDBACK_NORM_TOLERANCE)
            if reason is not None:
                self._count(unsent_replies=1)
                raise SafetyStop(f"withheld an EgmSensor whose planned pose has {reason}")
            self.planned = self._sent = planned
        message = codec.SensorMessage(self._next_seqno, self.latest.tm_ms, planned)
        self._next_seqno = (self._next_seqno + 1) % _SEQNO_MOD
        self._counts["replies"] += 1
        return carried.carry_sensor(message, self.config.version)

    def next_planned(self) -> Pose | None:
        """Take the planned pose :meth:`reply_carried` would send next, not building the reply.

        The ramp's step and its check, as there; the reply is counted later
        (:meth:`rested`). None, nothing changed, if the reply would be withheld.
        """
        planned = self.planned
        if planned is None or self.target is None:
            return None
        if not (planned is self.target and planned is self._sent):  # else at rest: sent as is
            period = self.config.sample_period_s
            planned = step_toward(
                planned, self.target, self.speed_mm_s * period, TURN_DEG_S * period
            )
            if unsafe_reason(planned, self.config.limits, FEEDBACK_NORM_TOLERANCE) is not None:
                return None
            self.planned = self._sent = planned
        return planned

    def resting(self) -> bool:
        """Whether every reply from now on repeats the last one's planned pose (the target's)."""
        planned = self.planned
        return planned is not None and planned is self.target and planned is self._sent

    def rested(self, cycles: int, tm_ms: int, time_us: int) -> None:
        """Count ``cycles`` fresh EgmRobots taken and answered unseen (``rest_carried``).

        The counters and seqnos move as if each had come; :attr:`latest` takes the last one's
        seqno and stamps (``tm_ms``, ``time_us``): the next datagram is judged by them, replaces it.
        """
        if cycles <= 0 or (latest := self.latest) is None:
            return
        self._count(received=cycles, replies=cycles)
        self._next_seqno = (self._next_seqno + cycles) % _SEQNO_MOD
        self._before_restart = self._chain = self.refusal = None  # as _fresh and on_datagram do
        self.latest = replace(latest, seqno=(latest.seqno + cycles) % _SEQNO_MOD, tm_ms=tm_ms,
                              time_us=time_us)

    def hold(self) -> None:
        """Make the present feedback pose the target; the planned pose ramps to it.

        Feedback that may not be adopted (outside the workspace) leaves the
        target at the planned pose: the robot stops where it was commanded.
        """
        if self.latest is None:
            return
        feedback = self.latest.feedback
        safe = unsafe_reason(feedback, self.config.limits, FEEDBACK_NORM_TOLERANCE) is None
        self.target = feedback if safe else self.planned

    # -- checkpoint (an emulated cell's bit-identical resume) -------------------------------

    def state_dict(self) -> dict[str, Any]:
        """The session as JSON-able values (the latest datagram as hex)."""

        def pose(p: Pose | None) -> list[float] | None:
            return None if p is None else [p.x_mm, p.y_mm, p.z_mm, *p.quaternion]

        raw = self.latest_raw
        return {
            "latest": None if raw is None else raw.hex(),
            "target": pose(self.target),
            "planned": pose(self.planned),
            "speed_mm_s": self.speed_mm_s,
            "session": self.session,
            "next_seqno": self._next_seqno,
            "origin_us": self.origin_us,
            "stats": dict(self._counts),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""

        def pose(v: list[float] | None) -> Pose | None:
            if v is None:
                return None
            x, y, z, w, qx, qy, qz = (float(c) for c in v[:7])
            return Pose(x, y, z, (w, qx, qy, qz))

        raw = state["latest"]
        self._latest_raw = None if raw is None else bytes.fromhex(raw)
        self.latest = (
            None if self._latest_raw is None
            else codec.decode_robot(self._latest_raw, self.config.version)
        )
        self.target = pose(state["target"])
        self.planned = pose(state["planned"])
        self.speed_mm_s = float(state["speed_mm_s"])
        self.session = int(state["session"])
        self._next_seqno = int(state["next_seqno"])
        origin = state.get("origin_us")
        self.origin_us = None if origin is None else int(origin)
        self._counts = asdict(EgmStats(**state["stats"]))

    # -- queries ----------------------------------------------------------------------------

    def controller_time_s(self) -> float:
        """The controller's time of the latest message, s: feedBack.time, else header.tm.

        feedBack.time is the controller's clock in µs since 1970 (manual p.38), counted
        from the first message read (:attr:`origin_us`) in whole µs: full resolution.
        """
        latest = self.latest
        return 0.0 if latest is None else self.time_at(latest.tm_ms, latest.time_us)

    def time_at(self, tm_ms: int, time_us: int | None) -> float:
        """The controller's time of a message stamped ``tm_ms`` and ``time_us``, s (as above)."""
        if time_us is not None and self.origin_us is not None:
            return (time_us - self.origin_us) / 1e6
        return tm_ms / 1000.0

    def controller_clock_us(self) -> int | None:
        """feedBack.time of the latest message: µs since 1970-01-01 UTC (None if not sent)."""
        return None if self.latest is None else self.latest.time_us

    def require_running(self) -> None:
        """Raise ``GuidanceStopped`` unless motors are on, EGM and RAPID run (:mod:`.stopped`)."""
        if self.latest is not None:  # (before a session: nothing known, nothing refused)
            require_running(self.latest)

    def in_position(self) -> bool:
        """True when planned, the controller's planned and its feedback are all at the target."""
        m = self.latest
        return m is not None and self.in_position_at(m.feedback, m.planned)

    def in_position_at(self, feedback: Pose | None, planned: Pose | None) -> bool:
        """:meth:`in_position` of an EgmRobot with this feedback and planned pose."""
        target = self.target  # (the PC's planned pose must be the target too)
        sent = self.planned
        if target is None or feedback is None or (sent is not target and sent != target):
            return False
        asked = (feedback, planned, target)
        known = self._in_position
        if known is not None and known[0] == asked:
            return known[1]  # the same poses as in the cycle before (at rest: most cycles)
        band_mm, band_deg = self.config.in_position_mm, self.config.in_position_deg
        turn = target.quaternion
        reached = (  # the feedback, then the controller's planned pose (if sent), in the band
            distance_mm(feedback, target) <= band_mm
            and angle_deg(feedback.quaternion, turn) <= band_deg
            and (planned is None or (distance_mm(planned, target) <= band_mm
                                     and angle_deg(planned.quaternion, turn) <= band_deg))
        )
        self._in_position = (asked, reached)
        return reached
