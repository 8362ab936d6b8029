"""The emulated robot controller as a running server: transport + engine + faults.

Start it in-process (this is what tests and the emulated cell use)::

    with ComputerLinkEmulator("pty", physics=cell_physics) as emu:
        robot = ComputerLinkRobot(LinkConfig(url=emu.address))
        ...
        assert emu.move_count == 1

or from a shell: ``python -m forcelearn.emulators.computer_link --transport pty``
(prints the path to open). ``transport="inproc"`` serves no thread: the driver
opens ``forcelearn-robot://NAME`` and every byte it writes is answered in its own
thread (the fastest route, for the emulated cell in this process).
"""

from __future__ import annotations

import logging
import threading
from typing import Literal

from forcelearn.deprecation import renamed
from forcelearn.devices import Pose
from forcelearn.emulators import registry
from forcelearn.emulators.clock import serial_char_time_s
from forcelearn.emulators.computer_link.controller import ControllerEngine
from forcelearn.emulators.computer_link.faults import ComputerLinkFaultConfig, FaultInjector
from forcelearn.emulators.computer_link.transport import InProcessEndpoint, TcpEndpoint
from forcelearn.emulators.computer_link.url_scheme import (
    REGISTRY_KIND,
    register_url_handler,
)
from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.pty_endpoint import PtyEndpoint
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m

log = logging.getLogger(__name__)

_ACK = framing.Control.ACK.wire
_WIRE_FAULTS = ("corrupt_byte", "drop_request", "drop_reply", "delay_ack", "drop_connection")
"""The faults on the frames (the arm's stall and never-in-position act in the engine)."""

POLL_S = 0.005
"""Longest wait of the server loop (s): bounds stop latency (motion runs on simulated time)."""


class ComputerLinkEmulator(Emulator):
    """A robot controller speaking the computer-link protocol on a pty or loopback TCP.

    Args:
        transport: "pty" (``address`` is a path), "tcp" (``address`` is
            ``socket://127.0.0.1:PORT``) or "inproc" (``address`` is
            ``forcelearn-robot://NAME``, reachable while started).
        config: arm geometry, limits, servo settings.
        physics: shared cell physics; the emulator writes every reached pose into it.
        faults: fault injection settings (default: none).
        port: TCP port (0 picks a free one); ignored for "pty" and "inproc".
        name: the in-process name (default: a fresh ``robot-<hex>``); "inproc" only.
        char_time_s: seconds per character on the emulated serial line
            (default: 9600 baud 8N1; 0: the wire costs no time). The pty or
            socket itself is as fast as the host; only simulated time counts.
    """

    def __init__(
        self,
        transport: Literal["pty", "tcp", "inproc"] = "pty",
        *,
        config: ArmConfig | None = None,
        physics: CellPhysics | None = None,
        faults: ComputerLinkFaultConfig | None = None,
        port: int = 0,
        char_time_s: float = serial_char_time_s(9600),
        name: str | None = None,
    ) -> None:
        if transport not in ("pty", "tcp", "inproc"):
            raise ValueError(f"transport must be 'pty', 'tcp' or 'inproc', got {transport!r}")
        self.engine = ControllerEngine(config, physics, char_time_s)
        self.faults = FaultInjector(faults)
        self._quiet_seen: tuple[object, bool] | None = None
        """(the fault config looked at, whether it is quiet): :meth:`_quiet`."""
        self.engine.motion.stall_fraction = self.faults.config.stall_fraction
        self.engine.never_in_position = self.faults.config.never_in_position
        self._endpoint: PtyEndpoint | TcpEndpoint | InProcessEndpoint
        if transport == "inproc":
            self._endpoint = InProcessEndpoint(name or registry.new_name("robot"))
        else:
            self._endpoint = PtyEndpoint("robot") if transport == "pty" else TcpEndpoint(port)
        self._reader = framing.FrameReader()
        self._generation = self._endpoint.generation
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._receive_lock = threading.Lock()
        self.bytes_received = 0
        """Bytes received from clients so far (tests use it to prove nothing was sent)."""

    @property
    def address(self) -> str:
        """What the driver opens: a pty path, ``socket://...`` or ``forcelearn-robot://NAME``."""
        return self._endpoint.address

    @property
    def move_count(self) -> int:
        """Moves the robot has executed (a retransmitted command never counts twice)."""
        return self.engine.move_count

    @property
    def pose(self) -> Pose:
        """The pose the robot has reached."""
        return self.engine.pose

    def _start_serving(self) -> None:
        """A daemon thread on the pty or socket; "inproc": register the name."""
        if isinstance(self._endpoint, InProcessEndpoint):
            register_url_handler()  # so its address opens with serial.serial_for_url
            registry.register(REGISTRY_KIND, self._endpoint.name, self)
        else:
            self._thread = threading.Thread(
                target=self._serve, name="robot-controller-emulator", daemon=True
            )
            self._thread.start()
        log.info("robot controller emulator serving on %s", self.address)

    def _release(self) -> None:
        """Stop serving, join the thread and release the transport."""
        self._stop.set()
        if isinstance(self._endpoint, InProcessEndpoint):  # a name not registered: no-op
            registry.unregister(REGISTRY_KIND, self._endpoint.name, self)
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            if self._thread.is_alive():  # pragma: no cover - would be a bug in _serve
                log.error("emulator thread did not stop within 5 s")
        self._thread = None
        self._endpoint.close()

    def connect(self, client: object) -> None:
        """Attach an in-process client port (``forcelearn-robot://``); one at a time."""
        if not isinstance(self._endpoint, InProcessEndpoint):
            raise ValueError("only an 'inproc' emulator takes in-process clients")
        if not self._started or self.closed:
            raise ConnectionRefusedError(f"{self.address} is not serving: start() it first")
        self._endpoint.attach(client)

    def disconnect(self, client: object) -> None:
        """Detach an in-process client port (it closed)."""
        if isinstance(self._endpoint, InProcessEndpoint):
            self._endpoint.detach(client)

    def receive(self, client: object, data: bytes) -> None:
        """Bytes an in-process client wrote: answered now, in the caller's thread."""
        with self._receive_lock:
            endpoint = self._endpoint
            if not isinstance(endpoint, InProcessEndpoint) or endpoint.client is not client:
                raise ConnectionResetError(
                    f"{self.address}: the connection was lost; reopen the port"
                )
            self._take(data)

    carries = True
    """Answer an in-process client's payloads without frames when it asks (:meth:`carry`);
    False: every request goes as frames (a test compares the two)."""

    def carry(self, client: object, payload: bytes) -> bytes | None:
        """An in-process client's request payload answered now; None: send it as a frame.

        What :meth:`receive` of the request's frame and of the client's DLE ACK of the
        reply gives, without the frames (``ControllerEngine.carry``): taken only while
        no fault is set, no real-time pace holds the clock and no partial frame waits.
        """
        with self._receive_lock:
            if not self._may_carry(client):
                return None
            self.bytes_received += framing.encoded_size(payload) + len(_ACK)
            return self.engine.carry(payload)

    def carry_status(self, client: object, payload: bytes) -> m.Status | None:
        """:meth:`carry` of a READ_STATUS request payload, the status its reply carries.

        ``ControllerEngine.carry_status``; None (nothing done: carry or send the
        payload instead) when :meth:`carry` would not carry it or it is not READ_STATUS.
        """
        with self._receive_lock:
            if not self._may_carry(client):
                return None
            status = self.engine.carry_status(payload)
            if status is not None:
                self.bytes_received += framing.encoded_size(payload) + len(_ACK)
            return status

    def _may_carry(self, client: object) -> bool:
        """Whether ``client``'s next payload may be carried (under the receive lock)."""
        endpoint = self._endpoint
        if not isinstance(endpoint, InProcessEndpoint) or endpoint.client is not client:
            raise ConnectionResetError(
                f"{self.address}: the connection was lost; reopen the port"
            )
        if not self.carries or self.engine.clock.time_scale > 0 or not self._quiet():
            return False
        if endpoint.generation != self._generation:  # as _take
            self._generation = endpoint.generation
            self._reader.clear()
        return not self._reader.pending

    def _quiet(self) -> bool:
        """No fault of the link can fire (each has probability 0).

        Kept per config object (frozen, its faults frozen too: a new config is a new
        object), so each carried request does not look at the five faults again.
        """
        config = self.faults.config
        seen = self._quiet_seen
        if seen is None or seen[0] is not config:
            seen = self._quiet_seen = (
                config, not any(getattr(config, name).probability for name in _WIRE_FAULTS))
        return seen[1]

    def _serve(self) -> None:
        while not self._stop.is_set():
            self._take(self._endpoint.read(POLL_S))

    def _take(self, data: bytes) -> None:
        """Feed received bytes to the frame reader and answer each complete frame."""
        if self._endpoint.generation != self._generation:  # a connection began or ended
            self._generation = self._endpoint.generation
            self._reader.clear()
        if data:
            self.bytes_received += len(data)
            for frame in self._reader.feed(self.faults.corrupt(data)):
                if self._answer(frame):
                    break

    def _answer(self, frame: framing.Frame) -> bool:
        """Answer one frame through the fault hooks; True if the connection was dropped."""
        if isinstance(frame, framing.DataFrame) and self.faults.drop_request():
            log.info("fault: request dropped")
            return False
        out = bytearray()
        for answer in self.engine.handle(frame):
            if answer.kind == "ack":
                delay = self.faults.ack_delay_s()
                if delay and self._stop.wait(delay):
                    return True
            if answer.executed and self.faults.drop_connection():
                log.info("fault: connection dropped after executing a request")
                self._endpoint.hang_up()
                self._reader.clear()
                return True
            if answer.kind == "reply" and self.faults.drop_reply():
                log.info("fault: reply dropped")
                continue
            out += self.faults.corrupt(answer.wire)
        if out:
            self.engine.clock.hold()  # real-time pace, if one is set
            self._endpoint.write(bytes(out))
        return False


__getattr__ = renamed(__name__, {"RobotControllerEmulator": ComputerLinkEmulator})
