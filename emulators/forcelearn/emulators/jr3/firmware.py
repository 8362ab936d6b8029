"""The JR3-to-CAN adapter's firmware on the cell's simulated clock: main loop, commands, samples.

The behaviour follows jr3-mbed-firmware-can (``main.cpp``, 2026-02) and its
sensor layer jr3-mbed-firmware (``Jr3Controller.cpp``), not our driver; what is
behind the wire is the shared :class:`~forcelearn.emulators.physics.cell.CellPhysics`
and a :class:`~.sensor_model.Jr3SensorModel`. The fidelity table in
docs/emulators.md lists every behaviour with its source and its test. This
module takes frames in (``_handle``) and hands frames out (``_deliver``); how
they reach a bus (a thread on a python-can bus, or in-process hosts) is
:class:`~forcelearn.emulators.jr3.node.Jr3EmulatorNode`'s job.

The firmware's main loop, on the cell's simulated clock (``physics.clock``):
every turn (1 ms apart, ``opcodes.loop_period_s``) it (1) answers a pending
SYNC with one force and one moment frame when the sensor runs (sync or async
mode), then clears the flag: a SYNC only sets that flag, so however many
arrive within a turn one pair comes back; (2) runs the queued commands (at
most 32 wait; the oldest is overwritten) and ACKs each; then sleeps.

============================  ===============================================
command (lengths lenient)     what the firmware does
============================  ===============================================
get state                     ACK, status 0 (ready) after the power-up init
start sync / start async      start the sensor (counter 0 when it was not
                              running), set the cut-off (0: unfiltered),
                              async: stream every period; ACK
stop                          stop the sensor: counter 0, offsets lost; ACK
zero offsets, set filter      store the present reading / the cut-off; ACK
get force / moment scales     7-byte ACK: 3 x uint16 (N / dN*m)
reset                         stop, re-read the sensor's 256-byte EEPROM (the
                              loop blocks meanwhile), ACK ready; no bootup
SYNC (exact id 0x080)         flag; answered at the next turn (see above)
============================  ===============================================

The frame counter counts complete sensor frames (``model.sync_sample_period_s``,
128.5 µs) since the sensor started, modulo 65536, and a sample is the filtered
reading of the latest complete frame; ``counter_meaning`` keeps the older
firmware's "one per pair sent" as a named behaviour. The bootup frame is sent
only at power-up (:meth:`Jr3EmulatorNode.inject_bootup`, the
``bootup_after_samples`` fault): the node is constructed powered-up and ready.

Time: every frame on the bus occupies it for its bits at ``bitrate``
(worst-case stuffing). A frame from the host starts when the host is ready
(the clock's present time) and the bus is free; the node's answers come at the
loop turn after it. Async streaming is paced by the host's wall clock
(:meth:`Jr3Firmware.emit_due`), each sample ``period_us`` of simulated time
after the previous.
"""

from __future__ import annotations

import collections
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from forcelearn.emulators.clock import Wire, can_frame_time_s
from forcelearn.emulators.jr3.faults import FrameHook, Jr3FaultConfig, apply_faults
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams, Jr3SensorModel
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.codec import ACK_NOT_INITIALISED, ACK_READY, Ack, Frame
from forcelearn.protocols.jr3_can.opcodes import DEFAULT_OPCODES, CounterMeaning, OpcodeMap
from forcelearn.protocols.jr3_can.scaling import cutoff_from_wire, full_scales_to_wire

NO_FAULTS = Jr3FaultConfig()

CarriedSample = tuple[tuple[int, int, int, int, int, int], int]
"""A sample handed over unframed (``Jr3Firmware._carry_sync``): the six raw counts
(Fx Fy Fz Mx My Mz, as the Forces and Moments messages carry them) and their counter."""

_AXES_BYTES = len(codec.encode(codec.Forces((0, 0, 0), 0), 1).data)
"""Data bytes of a forces or moments frame."""

COMMAND_QUEUE_DEPTH = 32
"""The firmware's receive queue (``CircularBuffer<CANMessage, 32>``; a full one overwrites)."""
EEPROM_BYTES = 256
"""Bytes of calibration the adapter re-reads from the sensor on reset and at power-up."""
POWER_UP_S = 2.0
"""The firmware sleeps 2 s after power-up before it sets up the bus and reads the EEPROM."""


@dataclass
class NodeStats:
    """What the node has done (counts)."""

    commands: int = 0
    rejected: int = 0
    samples: int = 0
    frames_lost: int = 0
    bootups: int = 0
    syncs: int = 0
    syncs_merged: int = 0
    """SYNCs that found the flag already set (one answer for them all)."""
    syncs_unanswered: int = 0
    """Turns whose SYNC flag found the sensor stopped (the firmware answers nothing)."""
    commands_overwritten: int = 0
    loop_turns: int = 0
    rejected_by_reason: dict[str, int] = field(default_factory=dict)


class Jr3Firmware:
    """The adapter's firmware: what it does with each frame, on the cell's clock.

    Args: as :class:`~forcelearn.emulators.jr3.node.Jr3EmulatorNode`'s (``physics``,
    ``node_id``, ``model``, ``faults``, ``seed``, ``initial_counter``, ``frame_hook``,
    ``opcodes``, ``bitrate``). A subclass puts the frames on a bus: it defines
    :meth:`_deliver`, feeds received frames to ``_handle`` under ``_lock`` and runs
    the turns due (``_pending_since``, ``_turn_after``, ``_run_turn``).
    """

    def __init__(
        self,
        physics: CellPhysics,
        *,
        node_id: int = 1,
        model: Jr3ModelParams | None = None,
        faults: Jr3FaultConfig | None = None,
        seed: int | None = 0,
        initial_counter: int = 0,
        frame_hook: FrameHook | None = None,
        opcodes: OpcodeMap = DEFAULT_OPCODES,
        bitrate: float | None = 1_000_000,
    ) -> None:
        if not 1 <= node_id <= 127:
            raise ValueError(f"node_id={node_id} is not 1..127")
        self.physics = physics
        self.node_id = node_id
        self.opcodes = opcodes
        self.faults = faults or NO_FAULTS
        self.frame_hook = frame_hook
        self.rng = np.random.default_rng(seed)
        self.model = Jr3SensorModel(model or Jr3ModelParams(), self.rng)
        self.frame_period_s = self.model.params.sync_sample_period_s
        """One complete sensor frame, s: the counter's unit of time."""
        self.loop_period_s = opcodes.loop_period_s
        self.eeprom_read_s = EEPROM_BYTES * self.frame_period_s
        """Time a reset blocks the loop: one calibration byte per sensor frame, s."""
        self.stats = NodeStats()
        self.mode = "idle"  # idle | sync | async: the sensor runs unless idle
        self.initialised = True  # the power-up initialisation ran before any host listened
        self.cutoff_hz = 0.0
        self.period_us = 0
        self._counter_base = initial_counter & 0xFFFF
        self._sent_counter = 0  # TRANSMITTED_SAMPLES: pairs sent since the start
        self._async_callback_set = False
        self.stream_start_s = 0.0
        """When the sensor (its thread) last started, simulated s."""
        self.clock = physics.clock
        self.bitrate = bitrate
        self._frame_times = tuple(0.0 if bitrate is None else can_frame_time_s(n, bitrate)
                                  for n in range(9))
        """Each frame's time on the bus by payload length, s (asked for every frame)."""
        self.bus_wire = Wire(self.clock)
        """The CAN bus as a timeline: frames never overlap."""
        self.last_sample_s = -math.inf
        """Time of the sensor frame the last sample read, s."""
        self._last_counts: list[int] | None = None
        self._last_async_s: float | None = None
        self._loop_origin_s = 0.0
        self._sync_flag_s: float | None = None
        """Arrival of the first SYNC of the pending flag (None: no flag)."""
        self._queue: collections.deque[tuple[float, codec.Message]] = collections.deque()
        self._lock = threading.RLock()
        self._next_emit = 0.0

    @property
    def counter(self) -> int:
        """The frame counter a sample would carry now."""
        with self._lock:
            return self._counter_at(self.clock.now_s)

    # ---- public control -------------------------------------------------
    def set_faults(self, faults: Jr3FaultConfig) -> None:
        """Change the wire faults now (e.g. go silent)."""
        with self._lock:
            self.faults = faults

    def inject_bootup(self) -> None:
        """Power-cycle now: sensor stopped, offsets lost, re-initialised, bootup frame sent."""
        with self._lock:
            self._power_cycle()

    def state_dict(self) -> dict[str, Any]:
        """Return what a bit-identical resume needs: model, stream, loop and bus state."""
        with self._lock:
            return {
                "model": self.model.state_dict(),
                "mode": self.mode,
                "cutoff_hz": self.cutoff_hz,
                "period_us": self.period_us,
                "counter_base": self._counter_base,
                "sent_counter": self._sent_counter,
                "stream_start_s": self.stream_start_s,
                "loop_origin_s": self._loop_origin_s,
                "bus": self.bus_wire.state_dict(),
                "last_sample_s": self.last_sample_s if math.isfinite(self.last_sample_s) else None,
                "last_counts": self._last_counts,
            }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a state from :meth:`state_dict`."""
        with self._lock:
            self.model.load_state_dict(state["model"])
            self.mode = str(state.get("mode", self.mode))
            self.cutoff_hz = float(state.get("cutoff_hz", self.cutoff_hz))
            self.period_us = int(state.get("period_us", self.period_us))
            self._counter_base = int(state.get("counter_base", 0)) & 0xFFFF
            self._sent_counter = int(state.get("sent_counter", 0))
            self.stream_start_s = float(state.get("stream_start_s", 0.0))
            self._loop_origin_s = float(state.get("loop_origin_s", 0.0))
            if "bus" in state:
                self.bus_wire.load_state_dict(state["bus"])
            last = state.get("last_sample_s")
            self.last_sample_s = -math.inf if last is None else float(last)
            counts = state.get("last_counts")
            self._last_counts = None if counts is None else [int(c) for c in counts]
            self._sync_flag_s = None
            self._queue.clear()

    def emit_due(self) -> float | None:
        """Stream what async mode owes by now; seconds to the next sample (None: not streaming)."""
        if self.mode != "async":  # sync or idle: nothing streams (checked again under the lock)
            return None
        with self._lock:
            if self.mode != "async":
                return None
            now = time.monotonic()
            if now >= self._next_emit:
                self._emit_async_sample()
                period_s = self.period_us * 1e-6
                # keep the schedule, but never burst to catch up after a stall
                self._next_emit = max(self._next_emit + period_s, now)
            return max(0.0, self._next_emit - time.monotonic())


    # ---- the firmware's main loop -------------------------------------------
    def _frame_time_s(self, data_bytes: int) -> float:
        return self._frame_times[data_bytes]

    def _pending_since(self) -> float | None:
        """Arrival of the oldest SYNC or command waiting for a turn (None: nothing waits)."""
        flag = self._sync_flag_s
        if not self._queue:
            return flag
        first = self._queue[0][0]
        return first if flag is None or first < flag else flag  # the earlier; the flag on a tie

    def _turn_after(self, t_s: float) -> float:
        """The first loop turn strictly after ``t_s`` (turns are ``loop_period_s`` apart)."""
        period = self.loop_period_s
        turns = math.floor((t_s - self._loop_origin_s) / period + 1e-9) + 1
        return self._loop_origin_s + max(turns, 1) * period

    def _run_turns_before(self, t_s: float) -> None:
        """Run the turns due before ``t_s`` that have work (the host did not wait for them)."""
        while True:
            due = self._pending_since()
            if due is None:
                return
            turn = self._turn_after(due)
            if turn > t_s:
                return
            self._run_turn(turn)

    def _run_turn(self, turn_s: float) -> None:
        """One turn of the main loop at ``turn_s``: the SYNC flag, then the queued commands."""
        self.stats.loop_turns += 1
        self.clock.advance_to(turn_s)
        if self._sync_flag_s is not None:
            self._sync_flag_s = None
            if self.mode != "idle" and self.initialised:
                self._emit_sample()
            else:
                self.stats.syncs_unanswered += 1
        while self._queue:
            _, message = self._queue.popleft()
            self.stats.commands += 1
            self._answer(message)

    def _arrive(self, data_bytes: int) -> float:
        """A frame of ``data_bytes`` put on the bus now: the turns due before it run; its end, s."""
        start = max(self.bus_wire.free_at_s, self.clock.now_s)
        self._run_turns_before(start)
        _, arrived = self.bus_wire.transmit(self._frame_time_s(min(data_bytes, 8)))
        self.clock.advance_to(arrived)
        return arrived

    def _flag_sync(self, arrived_s: float) -> None:
        """A SYNC arrived: set the loop's flag (SYNCs before the next turn share it)."""
        self.stats.syncs += 1
        if self._sync_flag_s is None:
            self._sync_flag_s = arrived_s
        else:
            self.stats.syncs_merged += 1

    def _carry_sync(self, node_id: int) -> CarriedSample | None:
        """A host's SYNC and the turn that answers it, the answer's counts not framed.

        What ``_handle`` of the SYNC frame and the next turn do, to the same clock,
        bus times, draws and counts; the answer (its Forces and Moments messages, the
        same counter) is returned as the six counts and the counter instead of encoded.
        None (nothing done: send the frame) unless the stream runs in sync mode for
        ``node_id`` with no fault, no frame hook, nothing waiting for a turn and
        ``_emit_sample`` not wrapped on the object (a wrapper sees each sample on the
        frames' route, which reads the same).
        """
        if (node_id != self.node_id or self.mode != "sync" or not self.initialised
                or self.faults is not NO_FAULTS or self.frame_hook is not None
                or self._pending_since() is not None
                or "_emit_sample" in self.__dict__):  # a hook on it (step_timeline) sees frames
            return None
        # _flag_sync(_arrive(0)) then _run_turn(_turn_after(flag)) written out for this case
        # (nothing waits for a turn, no flag set, the stream in sync mode), then
        # _emit_sample's two _send without a fault or hook: the same bus times, clock moves
        # and counts (tests/drivers/jr3_can/test_jr3_carried.py)
        wire, clock, times = self.bus_wire, self.clock, self._frame_times
        arrived = wire.send(times[0])  # a SYNC has no data
        stats = self.stats
        stats.syncs += 1
        stats.loop_turns += 1
        clock.advance_to(self._turn_after(arrived))
        sample = self._next_sample()
        duration = times[_AXES_BYTES]
        wire.send(duration)  # the Forces frame
        wire.send(duration)  # the Moments frame
        self._count_sample()  # no fault: no bootup after it
        return sample

    def _handle(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        arrived = self._arrive(len(msg.data))
        message = codec.decode_as_adapter(msg.arbitration_id, msg.data, self.node_id,
                                          is_extended_id=msg.is_extended_id,
                                          opcodes=self.opcodes)
        if message is None:
            self.stats.rejected += 1
            reason = "NOT_FOR_THIS_NODE"
            self.stats.rejected_by_reason[reason] = self.stats.rejected_by_reason.get(reason, 0) + 1
            return
        if isinstance(message, codec.Sync):
            self._flag_sync(arrived)
            return
        if len(self._queue) == COMMAND_QUEUE_DEPTH:
            self._queue.popleft()
            self.stats.commands_overwritten += 1
        self._queue.append((arrived, message))

    def _ack(self) -> Ack:
        return Ack(ACK_READY if self.initialised else ACK_NOT_INITIALISED)

    def _answer(self, message: codec.Message) -> None:
        """Run one command as the firmware's ``switch`` does, and ACK it."""
        ready = self.initialised
        match message:
            case codec.GetState():
                pass
            case codec.StartSync(cutoff_centi_hz=c) if ready:
                self._start("sync", c, 0)
            case codec.StartAsync(cutoff_centi_hz=c, period_us=p) if ready:
                if not self._async_callback_set:  # the firmware stops both threads first
                    self._stop_sensor()
                    self._async_callback_set = True
                self._start("async", c, p)
            case codec.Stop() if ready:
                self._stop_sensor()
            case codec.SetFilter(cutoff_centi_hz=c) if ready:
                self.cutoff_hz = cutoff_from_wire(c)
            case codec.ZeroOffsets() if ready and self.mode != "idle":
                self.physics.advance_to(self.clock.now_s)
                self.model.zero(self.physics.true_wrench())
            case codec.GetForceFullScales() | codec.GetMomentFullScales():
                forces, moments = full_scales_to_wire(np.asarray(self.model.params.full_scales))
                wanted = forces if isinstance(message, codec.GetForceFullScales) else moments
                scales = wanted if ready else (0, 0, 0)
                self._send(Ack(self._ack().status, scales))
                return
            case codec.Reset():
                self._stop_sensor()
                self.initialised = False
                self.clock.advance(self.eeprom_read_s)  # the loop blocks on the EEPROM read
                self.initialised = True
                self._loop_origin_s = self.clock.now_s
            case _:
                pass  # a command refused because not initialised: the ACK says so
        self._send(self._ack())

    def _start(self, mode: str, cutoff_centi_hz: int, period_us: int) -> None:
        if self.mode == "idle":  # a new sensor thread: counter and filter from 0
            self.stream_start_s = self.clock.now_s
            self._sent_counter = 0
            self.last_sample_s = -math.inf
            self._last_counts = None
            self.model.restart()
        self.mode = mode
        self.cutoff_hz = cutoff_from_wire(cutoff_centi_hz)
        self.period_us = period_us
        self._next_emit = time.monotonic()
        self._last_async_s = None

    def _stop_sensor(self) -> None:
        """The firmware's stopSensorThread: counter 0, offsets and filter state gone."""
        if self.mode != "idle":
            self.mode = "idle"
            self._counter_base = 0
            self.model.power_cycle()

    def _power_cycle(self) -> None:
        self.stats.bootups += 1
        self._stop_sensor()
        self._counter_base = 0
        self._async_callback_set = False
        self._sync_flag_s = None
        self._queue.clear()
        self.clock.advance(POWER_UP_S + self.eeprom_read_s)
        self.initialised = True
        self._loop_origin_s = self.clock.now_s
        self._send(codec.Bootup())

    # ---- samples ---------------------------------------------------------
    def _frames_at(self, t_s: float) -> int:
        """Complete sensor frames since the sensor started, at ``t_s``."""
        return max(0, math.floor((t_s - self.stream_start_s) / self.frame_period_s + 1e-9))

    def _counter_at(self, t_s: float) -> int:
        if self.mode == "idle":
            return 0
        return (self._counter_base + self._frames_at(t_s)) & 0xFFFF

    def _emit_async_sample(self) -> None:
        """The async thread's next send: ``period_us`` of simulated time after its last."""
        t = self.clock.now_s
        if self._last_async_s is not None:
            t = max(t, self._last_async_s + self.period_us * 1e-6)
        self._last_async_s = t
        self.clock.advance_to(t)
        self._emit_sample()

    def _emit_sample(self) -> None:
        """Send the latest complete sensor frame: its filtered reading and its counter."""
        (f_x, f_y, f_z, m_x, m_y, m_z), counter = self._next_sample()
        self._send(codec.Forces((f_x, f_y, f_z), counter))
        self._send(codec.Moments((m_x, m_y, m_z), counter))
        self._count_sample()

    def _next_sample(self) -> CarriedSample:
        """The latest complete sensor frame's six counts and its counter (one more sent)."""
        now = self.clock.now_s
        frames = self._frames_at(now)
        frame_s = self.stream_start_s + frames * self.frame_period_s
        if self._last_counts is None or frame_s > self.last_sample_s:
            dt = (frame_s - self.last_sample_s if math.isfinite(self.last_sample_s)
                  else self.frame_period_s)
            physics = self.physics
            physics.advance_to(now)
            # the wrench as floats (a hook on true_wrench, fault_inject's, is called by it)
            self._last_counts = self.model.measure(physics.true_wrench_values(), dt,
                                                   self.cutoff_hz)
            self.last_sample_s = frame_s
        raw = self._last_counts
        if self.opcodes.counter is CounterMeaning.TRANSMITTED_SAMPLES:
            counter = (self._counter_base + self._sent_counter) & 0xFFFF
        else:
            counter = (self._counter_base + frames) & 0xFFFF
        self._sent_counter += 1
        return (raw[0], raw[1], raw[2], raw[3], raw[4], raw[5]), counter

    def _count_sample(self) -> None:
        """A sample sent: counted; the fault's bootup after every n-th."""
        self.stats.samples += 1
        limit = self.faults.bootup_after_samples
        if limit is not None and self.stats.samples % limit == 0:
            self._power_cycle()

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
        _, end = self.bus_wire.transmit(self._frame_times[len(frame.data)])
        self.clock.advance_to(end)
        msg = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                          is_extended_id=False)
        self._deliver(msg, message)

    def _deliver(self, msg: can.Message, message: codec.Message) -> None:
        """Put ``msg`` (the frame of ``message``) on the bus: the transport's job."""
        raise NotImplementedError
