"""The EGM driver's UDP exchange with the controller: receive, answer, watchdog, session start.

:class:`EgmChannel` is the part of :class:`~forcelearn.drivers.egm.driver.EgmRobot`
that moves datagrams; the robot calls (read, move, wait) are built on it in
:mod:`.driver`, the session's rules (pairing, freshness, the ramp) are pure in
:mod:`.guidance`. The PC is the UDP server: it binds ``host:port`` and the
controller sends an EgmRobot message every sample period; each fresh one is
answered with an EgmSensor (:meth:`.guidance.Guidance.reply`). Two modes:

* **real** (``lockstep = False``): a receive thread answers every message at
  once with the latest planned pose, as abb_libegm does; the controller's
  clock runs on its own.
* **lockstep** (the emulated cell): nothing answers between calls;
  :meth:`EgmChannel._next_message` answers the held message and reads the
  next one, so the controller cycles spent between two host actions are
  fixed by the traffic alone (docs/egm.md, "Lockstep").

Errors: ``LinkTimeout`` (the controller fell silent for ``watchdog_s``, or
feedback is stale), ``LinkError`` (socket, or the receive thread ended), and
the reason a session start was refused (``EgmVersionMismatch``,
``SafetyStop``, ``ProtocolError``) when the watchdog ends a wait for one.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
import time
import weakref
from collections.abc import Callable
from typing import Any, Protocol, cast

from forcelearn.devices import Pose
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.drivers.egm.guidance import Guidance
from forcelearn.drivers.lifecycle import Driver
from forcelearn.errors import ForcelearnError, LinkError, LinkTimeout, SafetyStop
from forcelearn.protocols.egm import carried, codec

log = logging.getLogger(__name__)

POLL_S = 0.05
"""Receive slice of the real-mode thread (s): bounds how long close() waits for it."""
MAX_DATAGRAM = 65535


class DatagramSocket(Protocol):
    """What the driver needs of its UDP socket; an emulator's in-process end also has it."""

    def sendto(self, data: bytes, address: Any, /) -> int: ...  # noqa: D102
    def recvfrom(self, bufsize: int, /) -> tuple[bytes, Any]: ...  # noqa: D102
    def settimeout(self, value: float | None, /) -> None: ...  # noqa: D102
    def getsockname(self) -> Any: ...  # noqa: D102
    def close(self) -> None: ...  # noqa: D102


class CarryingSocket(DatagramSocket, Protocol):
    """An in-process controller's end that also hands datagrams over unencoded (lockstep).

    ``recv_carried``/``send_carried`` are ``recvfrom``/``sendto`` with
    :class:`~forcelearn.protocols.egm.carried.Carried` datagrams: neither side
    encodes a message nor parses one (the emulated cell's route; a socket
    that receives from a network has no such methods, and every datagram it
    gives is decoded and checked).
    """

    def recv_carried(self) -> tuple[carried.Datagram, Any]: ...  # noqa: D102
    def send_carried(self, data: carried.Datagram, address: Any, /) -> None: ...  # noqa: D102


Answer = Callable[[int, int, Pose, Pose], Pose | None]
"""The planned pose the PC answers an EgmRobot with, from its header.tm (ms), feedBack.time
(µs), feedBack.cartesian and planned.cartesian; None: a lockstep wait reads that EgmRobot."""


class RestingSocket(CarryingSocket, Protocol):
    """A carrying end that also runs in one jump the cycles whose answers the PC computes unseen.

    ``rest_carried(reply, address, answer)`` is ``send_carried(reply, address)``
    followed by the controller's cycles whose EgmRobot ``answer`` answers with
    a planned pose (the PC's next reply, taken), up to the first it answers
    None, which ``recv_carried`` gives next. It returns (cycles jumped, the
    last one's header.tm and feedBack.time). Each jumped cycle is one the
    driver would have taken and answered: :meth:`.guidance.Guidance.rested`
    counts them.
    """

    def rest_carried(  # noqa: D102
        self, data: carried.Datagram, address: Any, answer: Answer, /
    ) -> tuple[int, int, int]: ...


class EgmChannel(Driver):
    """One EGM UDP channel to one controller: the datagrams of a driver, and its lifetime.

    Constructing it binds the socket (``port`` tells which, when 0 was asked);
    :meth:`wait_for_session` (or :meth:`open`, or entering ``with``) then
    waits for the controller's first message. ``sock`` replaces the bound UDP
    socket with a ready one (the emulated cell's in-process controller,
    ``InProcessEgmController.socket()``; lockstep only); ``host`` and ``port``
    are then not used.
    """

    def __init__(self, config: EgmConfig, sock: DatagramSocket | None = None) -> None:
        self.config = config
        self._lock = threading.RLock()
        self._fresh = threading.Condition(self._lock)
        self._guidance = Guidance(config)
        self._failure: ForcelearnError | None = None
        self._pending: tuple[str, int] | None = None  # lockstep: address of an unanswered message
        self._fresh_count = 0  # fresh messages taken so far
        self._last_rx_s = 0.0  # host monotonic time of the latest fresh message (staleness)
        self._send_errors = 0
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._sock: DatagramSocket | None
        self._carrier: CarryingSocket | None = None
        self._rester: RestingSocket | None = None
        if sock is not None:
            if not config.lockstep:
                raise ValueError("a given socket (an in-process controller) needs lockstep = True")
            self._sock = sock
            self._carrier = _carrying(sock)
            if self._carrier is not None and callable(getattr(type(sock), "rest_carried", None)):
                self._rester = cast(RestingSocket, sock)
        else:
            self._sock = _bind(config.host, config.port)
        self.port: int = self._sock.getsockname()[1]
        if not config.lockstep:
            self._sock.settimeout(POLL_S)
            self._thread = threading.Thread(
                target=_serve, args=(weakref.ref(self),), name="egm-driver", daemon=True
            )
            self._thread.start()
        self._acquired = True
        log.info("EGM driver listening on %s:%d (%s)", config.host, self.port, config.version)

    # -- receiving --------------------------------------------------------------------------

    def _serve_once(self) -> bool:
        """Real mode: receive one datagram (or POLL_S of silence) and answer it at once.

        Returns False when the receive thread must end. Nothing received ends
        it (each datagram is used or counted); it ends on close, or if the
        socket itself fails (``LinkError``, raised by the next call). Anything
        else it meets is kept as a ``LinkError`` too, so a caller never sees a
        stale-feedback timeout in its place.
        """
        try:
            return self._receive_and_answer()
        except BaseException as exc:  # kept for the caller; the thread must say why it ended
            with self._lock:
                if self._failure is None and not self._stopping.is_set():
                    self._failure = LinkError(f"the EGM receive thread ended: {exc!r}")
                    self._failure.__cause__ = exc
                    log.error("EGM receive thread ended: %r", exc)
                self._fresh.notify_all()
            return False

    def _receive_and_answer(self) -> bool:
        if self._stopping.is_set():
            return False
        sock = self._require_socket()
        try:
            data, address = sock.recvfrom(MAX_DATAGRAM)
        except TimeoutError:
            return True
        except (ConnectionResetError, ConnectionRefusedError):
            return True  # an ICMP error of an earlier send (Windows reports them here)
        except OSError as exc:
            if not self._stopping.is_set():
                with self._lock:
                    self._failure = LinkError(f"EGM socket failed: {exc}")
                    self._fresh.notify_all()
            return False
        with self._lock:
            if self._take(data, address):
                self._answer(address)
            self._fresh.notify_all()
        return True

    def _answer(self, address: Any) -> None:
        """Send the reply to the controller at ``address``; a failed send is logged, not fatal."""
        try:
            datagram = self._guidance.reply()
        except SafetyStop as exc:
            log.error("EGM answer withheld: %s", exc)
            return
        try:
            self._require_socket().sendto(datagram, address)
        except OSError as exc:
            self._send_errors += 1
            if self._send_errors == 1:
                log.warning("cannot send EgmSensor to %s: %s (the controller will time out "
                            "if this goes on)", address, exc)

    def _take(self, data: carried.Datagram, address: Any) -> bool:
        fresh = self._guidance.on_datagram(data, address, time.monotonic())
        if fresh:
            self._fresh_count += 1
            self._last_rx_s = time.monotonic()
        return fresh

    def _next_message(self) -> None:
        """Let one controller cycle pass: answer (lockstep) and wait for the next fresh message."""
        watchdog = self.config.watchdog_s
        if not self.config.lockstep:
            seen = self._fresh_count
            deadline = time.monotonic() + watchdog
            while self._fresh_count == seen:
                remaining = deadline - time.monotonic()
                self._check()
                if remaining <= 0:
                    raise self._silent(watchdog)
                self._fresh.wait(remaining)
            return
        sock = self._require_socket()
        carrier = self._carrier
        if self._pending is not None:
            try:
                reply = self._guidance.reply_carried() if carrier else self._guidance.reply()
            except SafetyStop as exc:
                log.error("EGM answer withheld: %s", exc)
            else:
                self._send(reply, self._pending)
            self._pending = None
        deadline = time.monotonic() + watchdog
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise self._silent(watchdog)
            try:
                if carrier is not None:
                    data, address = carrier.recv_carried()
                else:
                    sock.settimeout(remaining)
                    data, address = sock.recvfrom(MAX_DATAGRAM)
            except TimeoutError:
                continue
            except (ConnectionResetError, ConnectionRefusedError):
                continue  # an ICMP error of an earlier send (Windows reports them here)
            except OSError as exc:
                raise LinkError(f"EGM socket failed: {exc}") from exc
            if self._take(data, address):
                self._pending = address
                return

    def _rest(self, ends: Callable[[list[float], Pose, Pose], int]) -> None:
        """Lockstep in process: answer the held message, jump the cycles answered unseen.

        The controller runs the cycles whose EgmRobot a wait would only
        answer, each answered with the ramp's next planned pose
        (:meth:`.guidance.Guidance.next_planned`), up to the first at which the
        wait ends or the answer would be withheld, which :meth:`_next_message`
        then reads as usual. ``ends(times, feedback, planned)`` is the index of the
        first of the controller ``times`` (:meth:`.guidance.Guidance.time_at`) at
        which the wait ends for that feedback and planned pose (``len(times)``:
        none), in order as one by one: the cycles at rest are asked in runs
        (:class:`_Answers`), the others one at a time.
        """
        rester, address, guidance = self._rester, self._pending, self._guidance
        if rester is None or address is None:
            return
        try:
            reply = guidance.reply_carried()
        except SafetyStop as exc:  # as _next_message: logged, nothing sent
            log.error("EGM answer withheld: %s", exc)
            self._pending = None
            return
        self._pending = None
        answer = _Answers(guidance, ends)
        try:
            jumped, tm_ms, time_us = rester.rest_carried(reply, address, answer)
        except OSError as exc:
            raise LinkError(f"cannot send EgmSensor to {address}: {exc}") from exc
        guidance.rested(jumped, tm_ms, time_us)
        self._fresh_count += jumped

    def _silent(self, watchdog: float) -> ForcelearnError:
        """The error of a watchdog's silence: why the controller's stream was refused, if so."""
        refusal = self._guidance.refusal
        if refusal is not None:
            return type(refusal)(f"{refusal} (no usable EgmRobot for {watchdog} s, "
                                 "robot.watchdog_s)")
        return LinkTimeout(self._silence(watchdog))

    def _silence(self, watchdog: float) -> str:
        return (
            f"no EgmRobot from the controller for {watchdog} s (robot.watchdog_s): is the RAPID "
            f"program running, and does its UDP Unicast Device point at this PC, port {self.port}?"
        )

    def _send(self, datagram: carried.Datagram, address: tuple[str, int]) -> None:
        try:
            sock, carrier = self._require_socket(), self._carrier
            if carrier is not None:
                carrier.send_carried(datagram, address)
            else:
                sock.sendto(bytes(datagram), address)
        except OSError as exc:
            raise LinkError(f"cannot send EgmSensor to {address}: {exc}") from exc

    def _require_socket(self) -> DatagramSocket:
        if self._sock is None:
            raise self._closed_error()
        return self._sock

    def _check(self) -> None:
        self._require_socket()
        if self._failure is not None:
            raise self._failure
        thread = self._thread
        if thread is not None and not thread.is_alive() and not self._stopping.is_set():
            raise LinkError("the EGM receive thread ended; close this driver and open a new one")

    # -- session ----------------------------------------------------------------------------

    def wait_for_session(self, timeout_s: float | None = None) -> Pose:
        """Wait (first_message_timeout_s) for the controller's first message; return its pose.

        Datagrams that cannot start a session are ignored while waiting; at
        the timeout, the reason of the latest one is raised (``EgmVersionMismatch``
        naming ``robot.version``, ``SafetyStop`` for feedback outside the
        workspace or not finite, ``ProtocolError`` for no Cartesian feedback),
        else ``LinkTimeout``.
        """
        limit = self.config.first_message_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + limit
        with self._lock:
            while self._guidance.latest is None:
                self._check()
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise self._silent(limit)
                if self.config.lockstep:
                    self._receive_first(remaining)
                else:
                    self._fresh.wait(remaining)
            self._check()
            assert self._guidance.target is not None
            return self._guidance.target

    def _receive_first(self, remaining: float) -> None:
        sock = self._require_socket()
        sock.settimeout(remaining)
        try:
            data, address = sock.recvfrom(MAX_DATAGRAM)
        except (TimeoutError, ConnectionResetError, ConnectionRefusedError):
            return
        except OSError as exc:
            raise LinkError(f"EGM socket failed: {exc}") from exc
        if self._take(data, address):
            self._pending = address

    def _latest(self) -> codec.RobotMessage:
        self._check()
        self._guidance.finish_latest()  # in process: the wait that read it may have left a field
        latest = self._guidance.latest
        if latest is None:
            raise LinkError("no EGM session yet: call wait_for_session() (or open_egm_robot)")
        if not self.config.lockstep:
            age = time.monotonic() - self._last_rx_s
            if age > self.config.stale_after_s:
                raise LinkTimeout(
                    f"stale EGM feedback: the latest EgmRobot is {age:.3f} s old "
                    f"(robot.stale_after_s = {self.config.stale_after_s})"
                )
        return latest


    # -- lifetime (forcelearn.drivers.lifecycle) -------------------------------------------

    def _is_ready(self) -> bool:
        with self._lock:
            return self._guidance.latest is not None

    def _make_ready(self) -> None:
        self.wait_for_session()

    def _release(self) -> None:
        """Hold the pose (best effort: one last answer in lockstep) and release the socket.

        The controller then sees silence and ends guidance after its CommTimeout.
        """
        with self._lock:
            if self._guidance.latest is not None:
                self._guidance.hold()
                if self._pending is not None and self._failure is None:
                    with contextlib.suppress(ForcelearnError):
                        self._send(self._guidance.reply(), self._pending)
                    self._pending = None
            self._stopping.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5 * POLL_S + 1.0)  # (collected in its own thread: it ends now)
        with self._lock:
            if self._sock is not None:
                self._sock.close()
                self._sock = None
                self._carrier = self._rester = None

    def _closed_error(self) -> LinkError:
        return LinkError(f"the EGM driver on port {self.port} is closed; open a new one")

    def _label(self) -> str:
        return f"EgmRobot on port {self.port}"

class _Answers:
    """The PC's answers to the cycles a lockstep wait jumps (``rest_carried``'s ``answer``).

    Called with an EgmRobot's header.tm, feedBack.time, feedback and planned
    pose: None if the wait ends at its controller time (``ends``, see
    :meth:`EgmChannel._rest`: the wait reads it), else the ramp's next planned
    pose (:meth:`.guidance.Guidance.next_planned`).
    """

    def __init__(self, guidance: Guidance, ends: Callable[[list[float], Pose, Pose], int]
                 ) -> None:
        self._guidance = guidance
        self._ends = ends
        self._time_at, self._next_planned = guidance.time_at, guidance.next_planned

    def __call__(self, tm_ms: int, time_us: int, feedback: Pose, planned: Pose) -> Pose | None:
        """The answer to one EgmRobot (None: the wait reads it)."""
        return (None if self._ends([self._time_at(tm_ms, time_us)], feedback, planned) == 0
                else self._next_planned())

    def at_rest(self, feedback: Pose, planned: Pose, stamps: list[tuple[int, int]]) -> int:
        """How many of the EgmRobots of ``stamps`` (in order) are answered with ``planned``.

        So while the ramp rests on ``planned`` (every answer repeats it: nothing
        of the guidance changes), up to the first at which ``ends`` holds, which
        is answered None; -1 when the ramp does not rest there (each is asked).
        """
        guidance = self._guidance
        if not guidance.resting() or guidance.planned is not planned:
            return -1
        time_at = self._time_at
        return self._ends([time_at(tm_ms, time_us) for tm_ms, time_us in stamps], feedback,
                          planned)


def _serve(driver_ref: weakref.ref[EgmChannel]) -> None:
    """The real-mode receive thread: answer every fresh message until the driver closes.

    It holds the driver only while it serves one datagram, so a driver dropped
    without :meth:`~EgmChannel.close` is still collected, warns and closes.
    """
    while True:
        driver = driver_ref()
        if driver is None or not driver._serve_once():
            return
        del driver


def _carrying(sock: DatagramSocket) -> CarryingSocket | None:
    """``sock`` if its class hands datagrams over unencoded, else None (bytes, decoded).

    Asked of the class, not the object: a wrapper that forwards unknown
    attributes (a recorder of ``sendto``) keeps the bytes it intercepts.
    """
    kind = type(sock)
    if callable(getattr(kind, "recv_carried", None)) and callable(
            getattr(kind, "send_carried", None)):
        return cast(CarryingSocket, sock)
    return None


def _bind(host: str, port: int) -> socket.socket:
    """A UDP socket bound to ``host:port`` (LinkError if it cannot be)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise LinkError(f"cannot bind EGM UDP {host}:{port}: {exc}") from exc
    return sock

