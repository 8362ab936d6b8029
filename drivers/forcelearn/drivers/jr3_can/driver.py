"""The JR3 force/torque sensor over a JR3-to-CAN adapter, on any python-can bus.

Satisfies :class:`forcelearn.devices.ForceSensor`. The bus is injected (socketcan,
pcan, kvaser, slcan, virtual...); the driver never shuts it down. Two ways to
read:

* **sync** (default): :meth:`Jr3CanSensor.read` sends SYNC and receives in the
  caller's thread until the matching force/moment pair arrives (about 1 ms on a
  real adapter: it answers at its next loop turn); emulated runs go as fast as
  the host and the emulator can.
* **async**: the adapter streams every ``period_us``; a ``can.Notifier`` thread
  feeds :class:`~.listener.Jr3Listener`, which calls ``on_sample`` callbacks
  (e.g. the force filter) for every paired sample; :meth:`read` returns the
  newest fresh one.

Initialisation (on :meth:`initialise`; on :meth:`~.Jr3CanSensor.open` and
entering ``with`` unless done; on the first read), as the public host driver
(yarp-devices Jr3Mbed) does it: get
state, start sync or async with the cut-off (0: unfiltered), read the full
scales unless configured, wait ``zero_settle_s`` and zero the offsets
(``zero_on_init``, on by default: the adapter's offsets are 0 after every
power-up, reset and stop, so without zeroing every reading holds the
sensor's raw bias). :meth:`close` sends stop and is idempotent
(:mod:`forcelearn.drivers.lifecycle`).

A bootup frame after the first initialisation (the adapter browned out or
was power-cycled) is **never** answered by zeroing here: the tool may be in
contact, and a zero taken there would hide the contact force. Every read
raises :class:`~forcelearn.errors.SensorRebooted` until the cell, with the
tool in free space, calls :meth:`Jr3CanSensor.reinitialise` (started again,
offsets 0) and zeroes (:func:`forcelearn.cell.retract_and_retare`).

Counter and losses: the adapter's frame counter counts sensor frames
(~7.8 kHz), so each sample carries the sensor time since the previous one
(``sensor_dt_s``); losses are counted where they are known: a SYNC with no
pair (``unanswered_syncs``, ``lost_frames``) and frames without a partner
(``unpaired_frames``). Sync mode keeps one SYNC in flight (the adapter answers
one per 1 ms loop turn).

Errors: :class:`SensorTimeout` (no ACK), :class:`SensorStale` (no sample in
``stale_timeout_s``), :class:`SensorBusError` (python-can errors, converted with
``raise ... from``), :class:`SensorError` (the adapter refuses a command).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Literal

import can
import numpy as np

from forcelearn.devices import WrenchSample
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.listener import Jr3Listener, Jr3Stats, SampleCallback
from forcelearn.drivers.lifecycle import Driver
from forcelearn.errors import (
    SensorBusError,
    SensorError,
    SensorRebooted,
    SensorStale,
    SensorTimeout,
)
from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.scaling import cutoff_to_wire, full_scales_from_wire

log = logging.getLogger(__name__)

NOTIFIER_POLL_S = 0.05
STOP_ACK_TIMEOUT_S = 0.1
SYNC_ATTEMPTS = 4
"""SYNCs sent for one sample before SensorStale, each waited for stale_timeout_s / 4."""


class Jr3CanSensor(Driver):
    """A JR3 sensor behind a JR3-to-CAN adapter.

    Args:
        bus: an open python-can bus (owned by the caller).
        config: node id, mode, cut-off, timeouts, optional full scales and log.
        on_sample: called with every paired sample (from the Notifier thread in
            async mode, from the reading thread in sync mode); keep it short.
    """

    def __init__(
        self,
        bus: can.BusABC,
        config: Jr3Config | None = None,
        *,
        on_sample: SampleCallback | None = None,
    ) -> None:
        self.bus = bus
        self.config = config or Jr3Config()
        writer = can.Logger(self.config.log_path) if self.config.log_path else None
        self._listener = Jr3Listener(
            self.config.node_id, self.config.opcodes, self.config.near_saturation_counts, writer
        )
        self._listener.unpaired_are_lost_samples = self.config.mode == "async"
        if on_sample is not None:
            self._listener.callbacks.append(on_sample)
        self._command_lock = threading.Lock()
        self._full_scales: np.ndarray | None = None
        self._cutoff_hz = self.config.cutoff_hz
        self._initialised = False
        self._ever_initialised = False
        self._rebooted = False
        self._last_seq = 0
        self._notifier: can.Notifier | None = None
        if self.config.mode == "async":
            try:
                self._notifier = can.Notifier(bus, [self._listener], timeout=NOTIFIER_POLL_S)
            except BaseException:
                self._listener.stop()
                raise
        self._acquired = True

    # ---- properties -----------------------------------------------------
    @property
    def full_scales(self) -> np.ndarray | None:
        """The six full scales in use (N, N, N, N*m, N*m, N*m), once initialised."""
        return None if self._full_scales is None else self._full_scales.copy()

    @property
    def cutoff_hz(self) -> float:
        """The adapter's low-pass cut-off last acknowledged (Hz)."""
        return self._cutoff_hz

    @property
    def stats(self) -> Jr3Stats:
        """A snapshot of the receive counts (samples, dropped, rejected, bootups...)."""
        return self._listener.stats()

    def add_sample_callback(self, callback: Callable[[WrenchSample], None]) -> None:
        """Call ``callback`` with every paired sample from now on."""
        self._listener.callbacks.append(callback)

    # ---- commands -------------------------------------------------------
    def initialise(self) -> None:
        """Run the host initialisation sequence (see the module docstring)."""
        self._initialise(zero=self.config.zero_on_init)

    def reinitialise(self) -> None:
        """After :class:`SensorRebooted`, with the tool in free space: start again, no zero.

        The offsets stay 0 (the raw bias reads) until the caller zeroes them.
        """
        self._initialise(zero=False)
        self._rebooted = False

    def _initialise(self, *, zero: bool) -> None:
        self._check_open()
        cfg = self.config
        with self._listener.cond:
            self._listener.bootup_pending = False
        self._initialised = False
        state = self._command(codec.GetState())
        log.info("JR3 node %d state: %s", cfg.node_id,
                 "ready" if state.ready else "not initialised")
        cutoff = cutoff_to_wire(self._cutoff_hz)
        start: codec.Message = codec.StartSync(cutoff)
        if cfg.mode == "async":
            start = codec.StartAsync(cutoff, cfg.period_us)
        # a started sensor counts from 0, and its first data may come before the ACK
        self._listener.restart_pairing()
        if not self._command(start).ready:
            raise SensorError(
                f"JR3 node {cfg.node_id} refused to start {cfg.mode} mode: check the sensor "
                "cable to the adapter and power-cycle the adapter"
            )
        if cfg.full_scales is not None:
            full_scales = np.asarray(cfg.full_scales, dtype=float)
        else:
            forces = self._command(codec.GetForceFullScales()).full_scales
            moments = self._command(codec.GetMomentFullScales()).full_scales
            if forces is None or moments is None:
                raise SensorError(
                    f"JR3 node {cfg.node_id} answered a full-scale query without full scales: "
                    "set jr3.full_scales in the configuration or update the adapter firmware"
                )
            try:
                full_scales = full_scales_from_wire(forces, moments)
            except ValueError as exc:
                raise SensorError(
                    f"JR3 node {cfg.node_id} reported force full scales {forces} N and moment "
                    f"full scales {moments} dN*m: {exc}; check the adapter's sensor cable and "
                    "EEPROM, or set jr3.full_scales in the configuration from the sensor's "
                    "calibration sheet"
                ) from exc
        self._full_scales = full_scales
        self._listener.set_full_scales(full_scales)
        if zero:
            time.sleep(cfg.zero_settle_s)
            self._command(codec.ZeroOffsets())
        self._initialised = self._ever_initialised = True
        log.info("JR3 node %d initialised: %s mode, cut-off %.2f Hz, full scales %s",
                 cfg.node_id, cfg.mode, self._cutoff_hz, full_scales.tolist())

    def zero_offsets(self) -> None:
        """Store the present reading as the offset (tool in free space, not touching)."""
        self._ensure_initialised()
        self._command(codec.ZeroOffsets())

    def set_cutoff(self, cutoff_hz: float) -> None:
        """Change the adapter's low-pass cut-off (Hz); returns once acknowledged."""
        wire = cutoff_to_wire(cutoff_hz)
        self._ensure_initialised()
        self._command(codec.SetFilter(wire))
        self._cutoff_hz = wire / 100.0

    def reset(self) -> None:
        """Reset the adapter (it stops and re-reads its EEPROM); the next read initialises it.

        The adapter sends no bootup after a reset and its counter starts again
        from 0, so pairing restarts here.
        """
        self._command(codec.Reset())
        self._listener.restart_pairing()
        self._initialised = False

    # ---- reading --------------------------------------------------------
    def read(self) -> WrenchSample:
        """Return the next fresh sample (sync: one per SYNC sent).

        Raises:
            SensorStale: no sample within ``stale_timeout_s``.
            SensorTimeout, SensorError, SensorBusError: see the module docstring.
        """
        self._ensure_initialised()
        sample = self._next_sample()
        if sample is None:
            raise self._on_bootup("read")
        return sample

    def read_many(self, count: int, window: int = 1) -> list[WrenchSample]:
        """Return ``count`` consecutive fresh samples (e.g. to average per robot step).

        Sync mode keeps one SYNC in flight, whatever ``window`` asks (it is kept
        for :class:`~forcelearn.devices.BatchForceSensor`): the adapter answers
        at most one SYNC per 1 ms loop turn, so a second SYNC sent before the
        answer would only trigger the other nodes on the bus. The samples come
        about 1 ms apart in sensor time. Async mode reads one by one.

        Raises:
            SensorStale: no sample for ``stale_timeout_s``; SensorError etc. as :meth:`read`.
        """
        if count < 0 or window < 1:
            raise ValueError(f"count={count} must be >= 0 and window={window} >= 1")
        if self.config.mode == "async":
            return [self.read() for _ in range(count)]
        self._ensure_initialised()
        out: list[WrenchSample] = []
        while len(out) < count:
            carried = self._carry_syncs(count - len(out), out)
            if carried is None:  # one read as _sync_sample sends it
                sample = self._sync_sample()
            elif isinstance(carried, bool):  # True: every SYNC carried gave its sample
                continue
            else:  # the carried SYNC gave no sample: its attempt goes on as _sync_sample's
                sample = self._sync_sample(carried)
            if sample is None:
                raise self._on_bootup("read_many")
            out.append(sample)
        return out

    def _sync_not_sent(self, exc: can.CanError) -> SensorBusError:
        """The error for a SYNC the CAN interface would not send (what to check)."""
        return SensorBusError(
            f"could not send sync to JR3 node {self.config.node_id}: {exc}; "
            "check the CAN interface is up (bitrate 1 Mbit/s) and the bus terminated"
        )

    def _carry_syncs(self, count: int, out: list[WrenchSample]
                     ) -> tuple[int, int] | Literal[True] | None:
        """Up to ``count`` SYNCs by an in-process bus's short cut, their samples put in ``out``.

        What ``count`` calls of :meth:`_sync_sample` do when each carried SYNC gives a
        sample, under one call to the bus (``Jr3EmulatorBus.carry_syncs``). Returns
        True (each SYNC carried gave its sample), (sequence, data frames) before a
        carried SYNC that gave none (its attempt then goes on in :meth:`_sync_sample`),
        or None when nothing was carried (send the frames).
        """
        carry = getattr(self.bus, "carry_syncs", None)
        lst = self._listener
        if (carry is None or self._notifier is not None or lst.writer is not None
                or lst.bootup_pending):  # as _carry_sync
            return None
        missed: list[tuple[int, int]] = []

        def take(raw: tuple[int, int, int, int, int, int], counter: int) -> bool:
            with lst.lock:
                seq, frames = lst.seq, lst.data_frames
            lst.on_carried_sample(raw, counter)
            with lst.lock:
                if lst.bootup_pending or lst.seq <= seq:
                    missed.append((seq, frames))
                    return False
                self._last_seq = lst.seq
                out.append(lst.latest)  # type: ignore[arg-type]  # a sample was just taken
            return True

        try:
            carried = carry(self.config.node_id, count, take)
        except can.CanError as exc:
            raise self._sync_not_sent(exc) from exc
        if carried is None:
            return None
        return missed[0] if missed else True

    @property
    def sample_period_s(self) -> float:
        """The nominal time between the samples this driver delivers, s.

        Sync: one per adapter loop turn (1 ms) when SYNCs follow the answers;
        async: the streaming period. The sensor's own time between two samples
        is on each sample (``sensor_dt_s``, from the frame counter).
        """
        if self.config.mode == "async":
            return max(self.config.period_us * 1e-6, self.config.opcodes.sensor_frame_period_s)
        return self.config.opcodes.loop_period_s

    def _sync_sample(self, carried: tuple[int, int] | None = None) -> WrenchSample | None:
        """Send one SYNC and wait for its pair; None if a bootup interrupts.

        A SYNC with no pair within a quarter of the stale timeout is counted lost
        (with the frames of it that never came) and sent again; after
        ``SYNC_ATTEMPTS`` misses in a row (the whole stale timeout) SensorStale.
        ``carried``: the first SYNC was carried already (:meth:`_carry_syncs`), the
        listener's sequence and data frames before it.
        """
        lst = self._listener
        wait_s = self.config.stale_timeout_s / SYNC_ATTEMPTS
        for attempt in range(SYNC_ATTEMPTS):
            if attempt == 0 and carried is not None:
                seq, frames = carried
            else:
                with lst.lock:
                    seq, frames = lst.seq, lst.data_frames
            if (attempt == 0 and carried is not None) or self._carry_sync():
                with lst.lock:  # the answer is taken: what the wait below finds at once
                    if lst.bootup_pending:
                        return None
                    if lst.seq > seq:
                        self._last_seq = lst.seq
                        return lst.latest
            else:
                self._send(codec.SYNC)

            def answered(before: int = seq) -> bool:
                return lst.seq > before or lst.bootup_pending

            got = self._wait_for(answered, wait_s)
            with lst.lock:
                if lst.bootup_pending:
                    return None
                if got:
                    self._last_seq = lst.seq
                    return lst.latest
                missing = max(0, 2 - (lst.data_frames - frames))
            lst.count_unanswered_sync(missing)
        raise SensorStale(
            f"no sample from JR3 node {self.config.node_id} within "
            f"{self.config.stale_timeout_s} s: check the adapter is powered and streaming; "
            "stop the robot"
        )

    def _next_sample(self) -> WrenchSample | None:
        """Wait for a sample newer than the last read; None if a bootup interrupts."""
        lst = self._listener
        cfg = self.config
        if cfg.mode == "sync":
            return self._sync_sample()
        with lst.cond:
            fresh = lst.latest is not None and (
                time.monotonic() - lst.latest.timestamp_s < cfg.stale_timeout_s
            )
            if not fresh:
                self._last_seq = lst.seq
        got = self._wait_for(lambda: lst.seq > self._last_seq or lst.bootup_pending,
                             cfg.stale_timeout_s)
        with lst.cond:
            if lst.bootup_pending:
                return None
            if not got:
                raise SensorStale(
                    f"no sample from JR3 node {cfg.node_id} within {cfg.stale_timeout_s} s: "
                    "check the adapter is powered and streaming; stop the robot"
                )
            self._last_seq = lst.seq
            return lst.latest

    # ---- plumbing -------------------------------------------------------
    def _ensure_initialised(self) -> None:
        self._check_open()
        with self._listener.cond:
            bootup = self._listener.bootup_pending
        if bootup and self._ever_initialised:
            raise self._on_bootup("a command")
        if self._rebooted:
            raise self._rebooted_error("a command")
        if bootup or not self._initialised:
            self.initialise()

    def _on_bootup(self, during: str) -> SensorRebooted:
        """A bootup frame arrived: the adapter lost its offsets; never zero here."""
        with self._listener.cond:
            self._listener.bootup_pending = False
        self._initialised = False
        self._rebooted = True
        log.warning("JR3 node %d rebooted during %s: offsets lost", self.config.node_id, during)
        return self._rebooted_error(during)

    def _rebooted_error(self, during: str) -> SensorRebooted:
        return SensorRebooted(
            f"JR3 node {self.config.node_id} rebooted (bootup frame, during {during}): its "
            "offsets are lost, so its readings are off by the raw bias; retract to free "
            "space, then reinitialise() and zero (the run does it); check the adapter's "
            "power supply",
            lost="offsets",
        )

    def _check_open(self) -> None:
        if self.closed:
            raise self._closed_error()
        if self._listener.bus_error is not None:
            if self._notifier is not None:  # its thread would spin on the failing bus
                self._notifier.stop(timeout=1.0)
            raise SensorBusError(
                f"CAN bus failed: {self._listener.bus_error}; check the adapter and restart"
            ) from self._listener.bus_error

    def _carry_sync(self) -> bool:
        """SYNC through an in-process bus's short cut, its answer taken; False: send the frame.

        The bus (``Jr3EmulatorBus.carry_sync``) hands the answer over unframed, as
        its six counts and counter, taken as its two frames would be after decoding
        (``Jr3Listener.on_carried_sample``); used in sync mode without a traffic log only.
        """
        carry = getattr(self.bus, "carry_sync", None)
        lst = self._listener
        if (carry is None or self._notifier is not None or lst.writer is not None
                or lst.bootup_pending):  # a bootup is answered before the SYNC's turn runs
            return False
        try:
            carried = carry(self.config.node_id)
        except can.CanError as exc:
            raise self._sync_not_sent(exc) from exc
        if carried is None:
            return False
        lst.on_carried_sample(*carried)
        return True

    def _send(self, message: codec.Message) -> None:
        frame = codec.encode(message, self.config.node_id, self.config.opcodes)
        msg = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                          is_extended_id=False, is_rx=False)
        try:
            self.bus.send(msg)
        except can.CanError as exc:
            raise SensorBusError(
                f"could not send {message.kind} to JR3 node {self.config.node_id}: {exc}; "
                "check the CAN interface is up (bitrate 1 Mbit/s) and the bus terminated"
            ) from exc
        self._listener.log_frame(msg)

    def _command(self, message: codec.Message, timeout_s: float | None = None) -> codec.Ack:
        """Send one command and return its ACK (one command in flight at a time)."""
        lst = self._listener
        timeout_s = self.config.ack_timeout_s if timeout_s is None else timeout_s
        with self._command_lock:
            with lst.cond:
                lst.acks.clear()
            self._send(message)
            if not self._wait_for(lambda: bool(lst.acks), timeout_s):
                raise SensorTimeout(
                    f"no ACK to {message.kind} from JR3 node {self.config.node_id} within "
                    f"{timeout_s} s: check power, node id, bitrate and wiring"
                )
            with lst.cond:
                return lst.acks.popleft()

    def _wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Wait until ``predicate()`` (checked under the listener's lock) or the timeout.

        With a Notifier (async) this waits on the condition; without one (sync)
        it receives from the bus in this thread and feeds the listener. Past the
        deadline it still takes what the bus already holds before giving up, so a
        host thread stalled by its machine does not call an answer that came lost.
        """
        lst = self._listener
        deadline = time.monotonic() + timeout_s
        while True:
            with lst.lock:
                if predicate():
                    return True
                failed = lst.bus_error is not None
                remaining = deadline - time.monotonic()
                if not failed and remaining > 0 and self._notifier is not None:
                    lst.sample_waiters += 1
                    try:
                        lst.cond.wait(remaining)
                    finally:
                        lst.sample_waiters -= 1
                    continue
            if failed:
                self._check_open()  # raises SensorBusError (outside the lock)
            if remaining <= 0 and self._notifier is not None:
                return False
            try:
                msg = self.bus.recv(max(remaining, 0.0))
            except can.CanError as exc:
                raise SensorBusError(
                    f"CAN receive failed: {exc}; check the CAN interface and restart"
                ) from exc
            if msg is not None:
                lst.on_message_received(msg)
            elif remaining <= 0:
                return False

    # ---- life cycle (forcelearn.drivers.lifecycle) ------------------------
    def _is_ready(self) -> bool:
        return self._initialised

    def _make_ready(self) -> None:
        self.initialise()

    def _release(self) -> None:
        """Send stop (best effort), stop the Notifier and the log."""
        try:
            if self._initialised and self._listener.bus_error is None:
                self._command(codec.Stop(), min(self.config.ack_timeout_s, STOP_ACK_TIMEOUT_S))
        except SensorError as exc:
            log.warning("JR3 node %d: stop not acknowledged on close (%s)",
                        self.config.node_id, exc)
        finally:
            if self._notifier is not None:
                self._notifier.stop(timeout=1.0)
            self._listener.stop()

    def _closed_error(self) -> SensorError:
        return SensorError(f"the JR3 sensor (node {self.config.node_id}) is closed; "
                           "create a new one")

    def _label(self) -> str:
        return f"Jr3CanSensor for node {self.config.node_id}"
