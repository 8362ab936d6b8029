"""Bus frames in, paired wrench samples out: the driver's ``can.Listener``.

Fed by a ``can.Notifier`` thread (async mode) or by the caller's own receive
loop (sync mode). Everything it learns is kept under one condition variable:
ACKs in arrival order, the latest sample and a sequence number, a pending
bootup, a bus error. It never raises out of ``on_message_received``: bad
frames are counted in :class:`Jr3Stats` and logged.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field

import can
import numpy as np

from forcelearn.devices import WrenchSample
from forcelearn.drivers.jr3_can.pairing import Pair, Pairer
from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.opcodes import CounterMeaning, OpcodeMap
from forcelearn.protocols.jr3_can.scaling import units_per_count

log = logging.getLogger(__name__)

SampleCallback = Callable[[WrenchSample], None]
_NOT_SATURATED = (False,) * 6


@dataclass
class Jr3Stats:
    """Counts of what the driver received (a snapshot copy is handed out)."""

    frames: int = 0
    samples: int = 0
    dropped_samples: int = 0
    """Samples known lost: SYNCs the adapter did not answer with a pair (sync mode), or
    frames left without a partner (async mode), plus counter gaps with a firmware whose
    counter counts pairs sent. Never the steps of a current adapter's counter: those are
    sensor time."""
    unanswered_syncs: int = 0
    """SYNCs after which no pair came within a quarter of the stale timeout."""
    lost_frames: int = 0
    """Force or moment frames of unanswered SYNCs that never came (sync mode)."""
    unpaired_frames: int = 0
    pending_frames: int = 0
    """Force or moment frames waiting for their partner (0..2)."""
    duplicate_samples: int = 0
    samples_before_full_scales: int = 0
    bootups: int = 0
    error_frames: int = 0
    other_nodes: int = 0
    rejected: Counter[str] = field(default_factory=Counter)

    @property
    def rejected_total(self) -> int:
        """All malformed frames, whatever the reason."""
        return sum(self.rejected.values())


class Jr3Listener(can.Listener):
    """Decode, pair and scale the frames of one adapter node."""

    def __init__(
        self,
        node_id: int,
        opcodes: OpcodeMap,
        near_saturation_counts: int,
        writer: can.Listener | None = None,
    ) -> None:
        self.node_id = node_id
        self.opcodes = opcodes
        self.near_saturation_counts = near_saturation_counts
        self.writer = writer
        self.writer_lock = threading.Lock()
        self.lock = threading.RLock()
        """The condition's lock: ``with lock`` where nothing waits or notifies (the hot
        path: one C call where the condition's ``with`` adds a Python frame each way)."""
        self.cond = threading.Condition(self.lock)
        self.sample_waiters = 0
        """Threads in ``cond.wait`` (counted by the waiter): a sample notifies only if one
        waits (notify_all with none waiting does nothing, at a cost on every sample)."""
        self.callbacks: list[SampleCallback] = []
        self.acks: deque[codec.Ack] = deque()
        self.latest: WrenchSample | None = None
        self.seq = 0
        self.bootup_pending = False
        self.bus_error: Exception | None = None
        self._per_count: list[float] | None = None
        """N and N*m per count of the full scales in use (every sample is scaled by it), as
        floats: six products in Python are numpy's elementwise product to the bit, cheaper."""
        self._pairer = Pairer(opcodes.counter)
        self._frame_period_s = (opcodes.sensor_frame_period_s
                                if opcodes.counter is CounterMeaning.SENSOR_FRAMES else None)
        self._stats = Jr3Stats()
        self.data_frames = 0
        """Force and moment frames received (for the driver's count of lost frames)."""
        self.unpaired_are_lost_samples = False
        """Async mode: each unpaired frame is a sample lost (a pair lost whole leaves no
        trace: the counter is sensor time). Sync mode counts unanswered SYNCs instead."""

    def set_full_scales(self, full_scales: np.ndarray | None) -> None:
        """Use these six full scales (N, N*m) from now on; None stops scaling."""
        with self.cond:
            self._per_count = (None if full_scales is None
                               else units_per_count(full_scales).tolist())

    @property
    def dropped_samples(self) -> int:
        """Samples known lost so far (cheap; no snapshot)."""
        return self._lost_samples()

    def _lost_samples(self) -> int:
        lost = self._pairer.dropped + self._stats.unanswered_syncs
        if self.unpaired_are_lost_samples:
            lost += self._pairer.unpaired
        return lost

    def count_unanswered_sync(self, frames_missing: int) -> None:
        """The driver's SYNC got no pair: one sample and ``frames_missing`` (0..2) frames lost."""
        with self.cond:
            self._stats.unanswered_syncs += 1
            self._stats.lost_frames += frames_missing

    def restart_pairing(self) -> None:
        """The adapter's counter starts again (start, reset): forget the last one."""
        with self.cond:
            self._pairer.restart()

    def stats(self) -> Jr3Stats:
        """Return a snapshot of the counts."""
        with self.cond:
            s = self._stats
            s.dropped_samples = self._lost_samples()
            s.unpaired_frames = self._pairer.unpaired
            s.pending_frames = self._pairer.pending
            s.duplicate_samples = self._pairer.duplicates
            return Jr3Stats(**{**s.__dict__, "rejected": Counter(s.rejected)})

    def log_frame(self, msg: can.Message) -> None:
        """Write one frame (received or sent) to the traffic log, if any."""
        if self.writer is not None:
            with self.writer_lock:
                self.writer.on_message_received(msg)

    def on_message_received(self, msg: can.Message) -> None:
        """Handle one received frame; never raises for bad frames."""
        self.log_frame(msg)
        sample: WrenchSample | None = None
        with self.lock:
            self._stats.frames += 1
            if msg.is_error_frame:
                self._stats.error_frames += 1
                log.warning("CAN error frame received (bus trouble: check wiring/termination)")
                return
            result = codec.decode(msg.arbitration_id, msg.data, is_extended_id=msg.is_extended_id,
                                  opcodes=self.opcodes)
            if isinstance(result, codec.Rejected) or msg.is_remote_frame:
                if msg.is_remote_frame or isinstance(result, codec.Decoded):
                    reason = "REMOTE_FRAME"  # a frame that decoded is rejected for being remote
                else:
                    reason = result.reason.name
                self._stats.rejected[reason] += 1
                log.debug("rejected frame id=%#x data=%s: %s", msg.arbitration_id,
                          bytes(msg.data).hex(), reason)
                return
            if result.node_id != self.node_id:
                self._stats.other_nodes += 1
                return
            sample = self._take(result.message)
        if sample is not None:
            for callback in self.callbacks:
                callback(sample)

    def on_carried(self, message: codec.Message) -> None:
        """Handle one message of this node that an in-process bus handed over unframed.

        As :meth:`on_message_received` of its frame after decoding (counted as a frame).
        """
        with self.lock:
            self._stats.frames += 1
            sample = self._take(message)
        if sample is not None:
            for callback in self.callbacks:
                callback(sample)

    def on_carried_all(self, messages: list[codec.Message]) -> None:
        """:meth:`on_carried` of each message (the lock taken once when no callback waits)."""
        if self.callbacks:  # each callback outside the lock, as on_carried calls it
            for message in messages:
                self.on_carried(message)
            return
        with self.lock:
            for message in messages:
                self._stats.frames += 1
                self._take(message)

    def on_carried_sample(self, raw: tuple[int, int, int, int, int, int], counter: int) -> None:
        """A sample an in-process bus handed over as its six counts and counter.

        :meth:`on_carried_all` of its Forces and Moments messages (two frames counted),
        without building them when no callback waits and no frame is pending.
        """
        if self.callbacks or self._pairer.pending:
            self.on_carried_all([codec.Forces((raw[0], raw[1], raw[2]), counter),
                                 codec.Moments((raw[3], raw[4], raw[5]), counter)])
            return
        with self.lock:
            self._stats.frames += 2
            self.data_frames += 2
            elapsed = self._pairer.step_to(counter)  # push_both without the Pair built
            if elapsed >= 0:
                self._sample_of(raw, counter, elapsed or None)

    def _take(self, message: codec.Message) -> WrenchSample | None:
        """Act on one decoded message of this node (under the lock); the sample it completes."""
        sample: WrenchSample | None = None
        if isinstance(message, codec.Forces | codec.Moments):
            self.data_frames += 1
            sample = self._pair(message)
        elif isinstance(message, codec.Ack):
            self.acks.append(message)
            self.cond.notify_all()
        elif isinstance(message, codec.Bootup):
            log.warning(
                "JR3 adapter node %d sent bootup: its offsets are lost (the cell re-zeroes)",
                self.node_id)
            self._stats.bootups += 1
            self._pairer.restart()
            self.bootup_pending = True
            self.cond.notify_all()
        return sample

    def _pair(self, frame: codec.Forces | codec.Moments) -> WrenchSample | None:
        pair = self._pairer.push(frame)
        if pair is None:
            return None
        return self._sample(pair)

    def _sample(self, pair: Pair) -> WrenchSample | None:
        """The sample of a completed pair (None before the full scales are known)."""
        return self._sample_of(pair.raw, pair.counter, pair.elapsed)

    def _sample_of(self, raw: tuple[int, int, int, int, int, int], counter: int,
                   elapsed: int | None) -> WrenchSample | None:
        """:meth:`_sample` of the pair ``(raw, counter)`` (no Pair built).

        ``elapsed``: counter steps since the last pair (None: the first after a start).
        """
        per_count = self._per_count
        if per_count is None:
            self._stats.samples_before_full_scales += 1
            return None
        limit = self.near_saturation_counts
        saturated: tuple[bool, ...] = _NOT_SATURATED
        if max(raw) >= limit or min(raw) <= -limit:
            saturated = tuple(abs(v) >= limit for v in raw)
        sensor_dt_s = None
        if elapsed is not None and self._frame_period_s is not None:
            sensor_dt_s = elapsed * self._frame_period_s
        # scaling.counts_to_wrench: counts (ints, exact as floats) x per count
        sample = WrenchSample.of(
            np.array([raw[0] * per_count[0], raw[1] * per_count[1], raw[2] * per_count[2],
                      raw[3] * per_count[3], raw[4] * per_count[4], raw[5] * per_count[5]]),
            time.monotonic(), counter, saturated, sensor_dt_s)
        self._stats.samples += 1
        self.latest = sample
        self.seq += 1
        if self.sample_waiters:
            self.cond.notify_all()
        return sample

    def on_error(self, exc: Exception) -> None:
        """Keep the first bus error from the Notifier thread for the next public call."""
        with self.cond:
            if self.bus_error is None:
                log.error("CAN bus error in the receive thread: %s", exc)
                self.bus_error = exc
            self.cond.notify_all()

    def stop(self) -> None:
        """Flush and close the traffic log (called by the Notifier on stop)."""
        if self.writer is not None:
            with self.writer_lock:
                self.writer.stop()
                self.writer = None
