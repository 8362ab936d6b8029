"""A JR3-to-CAN adapter node on a python-can bus: the adapter's firmware and how it reaches a bus.

What the adapter does with each frame (its main loop, commands and samples,
on the cell's simulated clock) is :class:`~.firmware.Jr3Firmware`; this module
puts it on a bus and gives it the emulators' lifecycle
(:class:`~forcelearn.emulators.lifecycle.Emulator`).

With a thread (a ``virtual`` bus), the thread takes every frame waiting on the
bus, then runs the loop turns they call for, and streams async samples when
due. In-process (``in_process=True``): no bus and no thread. The node registers
its ``channel`` name; a python-can bus opened as
``can.Bus(interface="forcelearn-jr3", channel=NAME)``
(:class:`~forcelearn.emulators.jr3.can_bus.Jr3EmulatorBus`) hands each frame
the host sends to :meth:`Jr3EmulatorNode.receive` and, when the host waits for
an answer, asks the node to run its next turn
(:meth:`Jr3EmulatorNode.serve_pending`): the clock then moves to that turn.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import can

from forcelearn.emulators import registry
from forcelearn.emulators.jr3.faults import FrameHook, Jr3FaultConfig
from forcelearn.emulators.jr3.firmware import (
    COMMAND_QUEUE_DEPTH,
    EEPROM_BYTES,
    NO_FAULTS,
    POWER_UP_S,
    CarriedSample,
    Jr3Firmware,
    NodeStats,
)
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.opcodes import DEFAULT_OPCODES, OpcodeMap

__all__ = [
    "COMMAND_QUEUE_DEPTH", "EEPROM_BYTES", "JOIN_TIMEOUT_S", "NO_FAULTS", "POLL_S", "POWER_UP_S",
    "REGISTRY_KIND", "Jr3EmulatorNode", "NodeStats",
]

log = logging.getLogger(__name__)

POLL_S = 0.02
"""Longest the thread blocks on the bus, so ``close()`` returns promptly."""
JOIN_TIMEOUT_S = 2.0
REGISTRY_KIND = "jr3"
"""Kind under which in-process nodes register (``can.Bus(interface="forcelearn-jr3")``)."""


class Jr3EmulatorNode(Jr3Firmware, Emulator):
    """An emulated JR3 adapter on a CAN bus.

    Args:
        physics: the shared cell; each sample reads ``physics.true_wrench()``.
        bus: the bus to use (not shut down by the node); default: a new
            ``virtual`` bus on ``channel``, shut down on close.
        channel: virtual channel name when no bus is given; with ``in_process``,
            the name ``forcelearn-jr3`` buses join.
        node_id: the adapter's node id (1..127).
        model: the sensor model (full scales, noise, bias, drift, frame period).
        faults: wire faults; change them at run time with :meth:`set_faults`.
        seed: seed of the node's ``numpy.random.Generator``.
        initial_counter: the counter when the sensor first starts (tests start near the wrap).
        frame_hook: called on each outgoing frame after the faults.
        opcodes: the firmware version to behave as (opcodes, counter meaning, loop period).
        bitrate: the bus bitrate for frame times, bit/s (None: frames cost no time); fixed
            at construction.
        in_process: no bus and no thread: reached by ``forcelearn-jr3`` buses.
    """

    def __init__(
        self,
        physics: CellPhysics,
        *,
        bus: can.BusABC | None = None,
        channel: str = "forcelearn-jr3",
        node_id: int = 1,
        model: Jr3ModelParams | None = None,
        faults: Jr3FaultConfig | None = None,
        seed: int | None = 0,
        initial_counter: int = 0,
        frame_hook: FrameHook | None = None,
        opcodes: OpcodeMap = DEFAULT_OPCODES,
        bitrate: float | None = 1_000_000,
        in_process: bool = False,
    ) -> None:
        super().__init__(physics, node_id=node_id, model=model, faults=faults, seed=seed,
                         initial_counter=initial_counter, frame_hook=frame_hook,
                         opcodes=opcodes, bitrate=bitrate)
        self.channel = channel
        self.in_process = in_process
        self._hosts: list[Callable[[can.Message], None]] = []
        self._stop = threading.Event()
        self._owns_bus = bus is None and not in_process
        self.bus: can.BusABC | None = None
        self._thread: threading.Thread | None = None
        if in_process:
            registry.register(REGISTRY_KIND, channel, self)
            self._mark_started()  # serving from construction (forcelearn.emulators.lifecycle)
            return
        self.bus = bus if bus is not None else can.Bus(interface="virtual", channel=channel)
        self._thread = threading.Thread(target=self._run, name=f"jr3-emulator-{node_id}",
                                        daemon=True)
        self._thread.start()
        self._mark_started()

    @property
    def address(self) -> str:
        """The CAN channel a host opens (``virtual`` or ``forcelearn-jr3``)."""
        return self.channel

    # ---- in-process hosts (forcelearn-jr3 buses) ----------------------------
    def attach_host(self, deliver: Callable[[can.Message], None]) -> None:
        """Deliver every frame the node sends to ``deliver`` (an in-process bus)."""
        with self._lock:
            if self._closed:
                raise can.CanOperationError(f"JR3 emulator {self.channel!r} is closed")
            self._hosts.append(deliver)

    def detach_host(self, deliver: Callable[[can.Message], None]) -> None:
        """Stop delivering to ``deliver``; returns silently if it was not attached."""
        with self._lock:
            if deliver in self._hosts:
                self._hosts.remove(deliver)

    @property
    def hosts(self) -> int:
        """In-process buses attached now."""
        with self._lock:
            return len(self._hosts)

    def receive(self, msg: can.Message) -> None:
        """A frame a host put on the bus: on the wire now, acted on at the next loop turn."""
        with self._lock:
            self._handle(msg)

    def serve_pending(self) -> bool:
        """The host waits: run the next loop turn if a SYNC or a command waits for it.

        Returns True when a turn ran (the clock moved to it), False when nothing was pending.
        """
        with self._lock:
            due = self._pending_since()
            if due is None:
                return False
            self._run_turn(self._turn_after(due))
            self.clock.hold()
            return True

    def carry_sync(self, node_id: int) -> CarriedSample | None:
        """An in-process host's SYNC answered now: its answer's counts and counter, not framed.

        What :meth:`receive` of the SYNC frame and :meth:`serve_pending` do, without
        the frames (``Jr3Firmware._carry_sync``); None when the frame must go instead
        (another host listens, a fault or hook is set, the stream is not in sync mode).
        """
        with self._lock:
            if self._closed or not self.in_process or len(self._hosts) != 1:
                return None
            carried = self._carry_sync(node_id)
            if carried is not None:
                self.clock.hold()
            return carried

    def carry_syncs(self, node_id: int, count: int,
                    take: Callable[[tuple[int, int, int, int, int, int], int], bool]) -> int | None:
        """Up to ``count`` SYNCs carried in turn, each answer handed to ``take`` at once.

        :meth:`carry_sync` ``count`` times with ``take(counts, counter)`` after each (the
        host's handling of the answer, before its next SYNC), under one hold of the node's
        lock; stops after an answer ``take`` refuses (False). Returns the SYNCs carried,
        None when :meth:`carry_sync` would answer None.
        """
        with self._lock:
            if self._closed or not self.in_process or len(self._hosts) != 1:
                return None
            done = 0
            while done < count:
                carried = self._carry_sync(node_id)
                if carried is None:
                    break
                self.clock.hold()
                done += 1
                if not take(*carried):
                    break
            return None if done == 0 else done

    def _release(self) -> None:
        """Stop the thread (joined) and shut down the bus if the node made it."""
        self._stop.set()
        if self.in_process:
            registry.unregister(REGISTRY_KIND, self.channel, self)
            with self._lock:
                self._hosts.clear()
            return
        assert self._thread is not None and self.bus is not None
        self._thread.join(JOIN_TIMEOUT_S)
        if self._thread.is_alive():
            log.warning("JR3 emulator thread did not stop within %.1f s", JOIN_TIMEOUT_S)
        if self._owns_bus:
            self.bus.shutdown()

    # ---- thread ---------------------------------------------------------
    def _run(self) -> None:
        assert self.bus is not None
        until_next: float | None = None
        while not self._stop.is_set():
            timeout = POLL_S if until_next is None else min(POLL_S, until_next)
            try:
                msg = self.bus.recv(timeout)
                while msg is not None:  # every frame on the bus now, before the next turn
                    self.receive(msg)
                    msg = self.bus.recv(0)
            except can.CanError:
                if self._stop.is_set():
                    return
                log.exception("JR3 emulator: bus receive failed; stopping the node")
                return
            while self.serve_pending():
                pass
            until_next = self.emit_due()


    def _deliver(self, msg: can.Message, message: codec.Message) -> None:
        """Hand ``msg`` to the in-process hosts, or send it on the bus (a failure loses it)."""
        if self.in_process:
            msg.timestamp = time.time()
            msg.channel = self.channel
            for deliver in self._hosts:
                deliver(msg)
            return
        assert self.bus is not None
        try:
            self.bus.send(msg)
        except can.CanError:
            self.stats.frames_lost += 1
            log.warning("JR3 emulator: could not send %s", message.kind, exc_info=True)
