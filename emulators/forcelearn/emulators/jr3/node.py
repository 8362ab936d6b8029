"""A JR3-to-CAN adapter node on a python-can bus, answering the host like the real one.

The node reuses the driver's codec, so it speaks exactly the protocol the
driver expects, and differs from the device only in what is behind the wire:
the shared :class:`~forcelearn.emulators.physics.cell.CellPhysics` and a
:class:`~.sensor_model.SensorModel`. One thread receives commands and, in
async mode, emits a sample every period; ``close()`` stops and joins it.

============================  ===============================================
command                       answer
============================  ===============================================
get state                     ACK, status 0 once started, 1 after (re)boot
start sync / start async      ACK 0 and enter the mode (ACK 1 if cut-off or
                              period is 0)
stop, set filter, zero        ACK 0 (zero stores the present reading)
get force / moment scales     7-byte ACK: 3 x uint16 (N / dN*m)
reset                         ACK 0, then reboot: bootup frame, counter 0,
                              offsets cleared, idle and not initialised
SYNC (sync mode only)         one force frame and one moment frame
============================  ===============================================

Time (simulated, on the cell's clock, ``physics.clock``): every frame on the
bus occupies it for its bits at ``bitrate`` (worst-case stuffing), one after
the other; a frame from the host starts when the host is ready (the clock's
present time) and the bus is free, and the node's answers follow it. A SYNC
latches a sample when it has arrived, but never sooner than one internal
sample period after the previous sample; the physics is advanced to that
instant first, so the sample sees the robot and the sponge as they are then.
The clock ends at the last bit of the answer. Async streaming is paced by the
host's wall clock (the cell uses sync mode, which is deterministic).

In-process (``in_process=True``): no bus and no thread. The node registers
its ``channel`` name; a python-can bus opened as
``can.Bus(interface="forcelearn-jr3", channel=NAME)``
(:class:`~forcelearn.emulators.jr3.can_bus.Jr3EmulatorBus`) hands each frame
the host sends to :meth:`Jr3EmulatorNode.receive`, in the host's thread, and
takes the answers before ``send`` returns.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from forcelearn.emulators import registry
from forcelearn.emulators.clock import Wire, can_frame_time_s
from forcelearn.emulators.jr3.faults import FaultConfig, FrameHook, apply_faults
from forcelearn.emulators.jr3.sensor_model import SensorModel, SensorModelParams
from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.codec import Ack, Decoded, Frame
from forcelearn.protocols.jr3_can.opcodes import DEFAULT_OPCODES, OpcodeMap
from forcelearn.protocols.jr3_can.scaling import cutoff_from_wire, full_scales_to_wire

log = logging.getLogger(__name__)

NO_FAULTS = FaultConfig()

POLL_S = 0.02
"""Longest the thread blocks on the bus, so ``close()`` returns promptly."""
JOIN_TIMEOUT_S = 2.0
REGISTRY_KIND = "jr3"
"""Kind under which in-process nodes register (``can.Bus(interface="forcelearn-jr3")``)."""


@dataclass
class NodeStats:
    """What the node has done (counts)."""

    commands: int = 0
    rejected: int = 0
    samples: int = 0
    frames_lost: int = 0
    bootups: int = 0
    rejected_by_reason: dict[str, int] = field(default_factory=dict)


class Jr3EmulatorNode(Emulator):
    """An emulated JR3 adapter on a CAN bus.

    Args:
        physics: the shared cell; each sample reads ``physics.true_wrench()``.
        bus: the bus to use (not shut down by the node); default: a new
            ``virtual`` bus on ``channel``, shut down on close.
        channel: virtual channel name when no bus is given; with ``in_process``,
            the name ``forcelearn-jr3`` buses join.
        node_id: the adapter's node id (1..127).
        model: the sensor model (full scales, noise, bias, drift).
        faults: wire faults; change them at run time with :meth:`set_faults`.
        seed: seed of the node's ``numpy.random.Generator``.
        initial_counter: first frame counter (tests start near the 16-bit wrap).
        frame_hook: called on each outgoing frame after the faults.
        opcodes: the opcode map to speak.
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
        model: SensorModelParams | None = None,
        faults: FaultConfig | None = None,
        seed: int | None = 0,
        initial_counter: int = 0,
        frame_hook: FrameHook | None = None,
        opcodes: OpcodeMap = DEFAULT_OPCODES,
        bitrate: float | None = 1_000_000,
        in_process: bool = False,
    ) -> None:
        if not 1 <= node_id <= 127:
            raise ValueError(f"node_id={node_id} is not 1..127")
        self.physics = physics
        self.node_id = node_id
        self.opcodes = opcodes
        self.faults = faults or NO_FAULTS
        self.frame_hook = frame_hook
        self.rng = np.random.default_rng(seed)
        self.model = SensorModel(model or SensorModelParams(), self.rng)
        self.stats = NodeStats()
        self.mode = "idle"  # idle | sync | async
        self.initialised = False
        self.cutoff_hz = 0.0
        self.period_us = 0
        self.counter = initial_counter & 0xFFFF
        self.clock = physics.clock
        self.bitrate = bitrate
        self._frame_times = tuple(0.0 if bitrate is None else can_frame_time_s(n, bitrate)
                                  for n in range(9))
        """Each frame's time on the bus by payload length, s (asked for every frame)."""
        self.bus_wire = Wire(self.clock)
        """The CAN bus as a timeline: frames never overlap."""
        self.last_sample_s = -math.inf
        self.channel = channel
        self.in_process = in_process
        self._hosts: list[Callable[[can.Message], None]] = []
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._next_emit = 0.0
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

    # ---- public control -------------------------------------------------
    def set_faults(self, faults: FaultConfig) -> None:
        """Change the wire faults now (e.g. go silent)."""
        with self._lock:
            self.faults = faults

    def inject_bootup(self) -> None:
        """Reboot now: send a bootup frame, clear offsets, go idle and uninitialised."""
        with self._lock:
            self._reboot()

    def state_dict(self) -> dict[str, Any]:
        """Return what a bit-identical resume needs: model (rng, bias, offset) and counter."""
        with self._lock:
            return {
                "model": self.model.state_dict(),
                "counter": self.counter,
                "bus": self.bus_wire.state_dict(),
                "last_sample_s": self.last_sample_s if math.isfinite(self.last_sample_s) else None,
            }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a state from :meth:`state_dict`."""
        with self._lock:
            self.model.load_state_dict(state["model"])
            self.counter = int(state["counter"]) & 0xFFFF
            if "bus" in state:
                self.bus_wire.load_state_dict(state["bus"])
            last = state.get("last_sample_s")
            self.last_sample_s = -math.inf if last is None else float(last)

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
        """A frame a host put on the bus: handled now, answers delivered before return."""
        with self._lock:
            self._handle(msg)

    def emit_due(self) -> float | None:
        """Stream what async mode owes by now; seconds to the next sample (None: not streaming)."""
        with self._lock:
            if self.mode != "async":
                return None
            now = time.monotonic()
            if now >= self._next_emit:
                self._emit_sample()
                period_s = self.period_us * 1e-6
                # keep the schedule, but never burst to catch up after a stall
                self._next_emit = max(self._next_emit + period_s, now)
            return max(0.0, self._next_emit - time.monotonic())

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
            except can.CanError:
                if self._stop.is_set():
                    return
                log.exception("JR3 emulator: bus receive failed; stopping the node")
                return
            if msg is not None:
                self.receive(msg)
            until_next = self.emit_due()

    def _frame_time_s(self, data_bytes: int) -> float:
        return self._frame_times[data_bytes]

    def _handle(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        _, arrived = self.bus_wire.transmit(self._frame_time_s(len(msg.data)))
        self.clock.advance_to(arrived)
        result = codec.decode(msg.arbitration_id, msg.data, is_extended_id=msg.is_extended_id,
                              opcodes=self.opcodes)
        if not isinstance(result, Decoded):
            self.stats.rejected += 1
            key = result.reason.name
            self.stats.rejected_by_reason[key] = self.stats.rejected_by_reason.get(key, 0) + 1
            return
        message = result.message
        if isinstance(message, codec.Sync):
            if self.mode == "sync":
                self._emit_sample()
            self.clock.hold()
            return
        if result.node_id != self.node_id or message.kind in ("ack", "forces", "moments",
                                                              "bootup"):
            return
        self.stats.commands += 1
        self._answer(message)
        self.clock.hold()

    def _answer(self, message: codec.Message) -> None:
        forces, moments = full_scales_to_wire(np.asarray(self.model.params.full_scales))
        match message:
            case codec.GetState():
                self._send(Ack(0 if self.initialised else 1))
            case codec.StartSync(cutoff_centi_hz=c) if c > 0:
                self._start("sync", c, 0)
            case codec.StartAsync(cutoff_centi_hz=c, period_us=p) if c > 0 and p > 0:
                self._start("async", c, p)
            case codec.StartSync() | codec.StartAsync():
                self._send(Ack(1))
            case codec.Stop():
                self.mode = "idle"
                self._send(Ack(0))
            case codec.SetFilter(cutoff_centi_hz=c):
                self.cutoff_hz = cutoff_from_wire(c)
                self._send(Ack(0))
            case codec.ZeroOffsets():
                self.physics.advance_to(self.clock.now_s)
                self.model.zero(self.physics.true_wrench())
                self._send(Ack(0))
            case codec.GetForceFullScales():
                self._send(Ack(0, forces))
            case codec.GetMomentFullScales():
                self._send(Ack(0, moments))
            case codec.Reset():
                self._send(Ack(0))
                self._reboot()

    def _start(self, mode: str, cutoff_centi_hz: int, period_us: int) -> None:
        self.mode = mode
        self.cutoff_hz = cutoff_from_wire(cutoff_centi_hz)
        self.period_us = period_us
        self.initialised = True
        self._next_emit = time.monotonic()
        self._send(Ack(0))

    def _reboot(self) -> None:
        self.stats.bootups += 1
        self.mode = "idle"
        self.initialised = False
        self.counter = 0
        self.model.power_cycle()
        self._send(codec.Bootup())

    def _emit_sample(self) -> None:
        period = self.model.params.sync_sample_period_s
        if self.mode == "async":  # streamed samples are period_us apart in the cell's time
            period = max(period, self.period_us * 1e-6)
        t = max(self.clock.now_s, self.last_sample_s + period)
        dt = period if not math.isfinite(self.last_sample_s) else t - self.last_sample_s
        self.last_sample_s = t
        self.clock.advance_to(t)
        self.physics.advance_to(t)
        raw = self.model.measure(self.physics.true_wrench(), dt, self.cutoff_hz)
        self._send(codec.Forces((raw[0], raw[1], raw[2]), self.counter))
        self._send(codec.Moments((raw[3], raw[4], raw[5]), self.counter))
        self.counter = (self.counter + 1) & 0xFFFF
        self.stats.samples += 1
        limit = self.faults.bootup_after_samples
        if limit is not None and self.stats.samples % limit == 0:
            self._reboot()

    def _send(self, message: codec.Message) -> None:
        encoded = codec.encode(message, self.node_id, self.opcodes)
        frame: Frame | None = encoded
        if self.faults is not NO_FAULTS:  # the default: nothing to draw
            frame = apply_faults(encoded, self.faults, self.rng)
        if frame is not None and self.frame_hook is not None:
            frame = self.frame_hook(frame)
        if frame is None:
            self.stats.frames_lost += 1
            return
        _, end = self.bus_wire.transmit(self._frame_time_s(len(frame.data)))
        self.clock.advance_to(end)
        msg = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                          is_extended_id=False)
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
