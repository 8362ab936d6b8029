"""An emulated ATI Net F/T box on loopback: RDT over UDP, READCALINFO over TCP, two XML pages.

The emulator reuses the driver's pure codec (:mod:`forcelearn.protocols.netft`),
so it speaks exactly the bytes a box does, and differs from one only in what
is behind the wire: the shared :class:`~forcelearn.emulators.physics.cell.CellPhysics`
and a :class:`~.sensor_model.NetFtSensorModel`. Every server binds 127.0.0.1.

===============================  ============================================
request (UDP)                    answer
===============================  ============================================
start real-time (0x0002), N > 0  N records (``rdt_sequence`` 1..N), one per
                                 datagram, then silence
start real-time, N = 0           records at the RDT rate (wall-time paced)
                                 until stop or a new start
start buffered (0x0003), N > 0   the same N records, ``rdt_buffer_size`` to a
                                 datagram (a last, shorter datagram holds the
                                 rest: our choice, the manual is silent)
start buffered, N = 0            full datagrams at RDT rate / buffer size
stop (0x0000)                    nothing; streaming stops
set software bias (0x0042)       nothing; the present reading becomes zero
reset threshold latch (0x0041)   nothing (threshold monitoring not modelled)
wrong size or header             nothing; counted in ``stats.rejected`` and
                                 by reason in ``stats.rejected_by_reason``
                                 (``REQUEST_HEADER``, ``REQUEST_SIZE``); a
                                 stream goes on
any other command                nothing; counted likewise (``COMMAND``); a
                                 stream goes on
===============================  ============================================

READCALINFO (TCP) and the two XML pages (HTTP) are served by
:mod:`forcelearn.emulators.netft.calibration_servers`, which this module starts
and stops with the box.

Time
----
A finite request is answered on the cell's :class:`~forcelearn.emulators.clock.SimClock`:
record i is sampled at ``t_i = t_0 + i / rdt_rate_hz`` with
``t_0 = max(clock.now_s, last sample + period)``; for each, the physics is
moved to ``t_i`` (``physics.advance_to(t_i)``, if the physics has that method:
it is being added to ``CellPhysics``; until then the pose is whatever the robot
emulator last set) and ``physics.true_wrench()`` is read. The clock is moved to
the last record's time and :meth:`SimClock.hold` paces the answer (in slices of
about 1 ms of simulated time when a pace is set). So a burst costs the simulated
time a real box would spend, whatever the host's speed. Infinite streaming
(sample count 0, for ``check``) is paced by the wall clock instead.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.netft.calibration_servers import (
    HOST,
    CalInfoServer,
    XmlServer,
    bind_loopback,
    calibration_fields,
    settings_fields,
    xml_page,
)
from forcelearn.emulators.netft.faults import FaultCounts, NetFtFaults, RecordsHook, apply_faults
from forcelearn.emulators.netft.sensor_model import NetFtModelParams, NetFtSensorModel
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols import netft as protocol
from forcelearn.protocols.netft import Command, Record

__all__ = [
    "DEFAULT_RDT_RATE_HZ", "HOST", "INTERNAL_SAMPLE_RATE_HZ", "MAX_RDT_RATE_HZ",
    "EmulatorStats", "NetFtEmulator", "start_emulated_netft",
]

log = logging.getLogger(__name__)
DEFAULT_RDT_RATE_HZ = 7000.0
"""The Net F/T's maximum RDT output rate (manual §10: "up to 7000 Hz"); the factory
setting of a given box may be lower: ``forcelearn check`` prints the box's ``comrdtrate``."""
MAX_RDT_RATE_HZ = 7000.0
"""Fastest RDT rate the emulated box streams at, records/s: the Net F/T's maximum (manual
§10, "up to 7000 Hz"; ATI's Ethernet Axia manual: internal sample rate 7000 per s)."""
INTERNAL_SAMPLE_RATE_HZ = 7000.0
"""The box's internal sample rate, samples/s: ``ft_sequence`` counts these from power-up,
whatever the RDT output rate (manual §10 on ft_sequence; ATI's Ethernet Axia manual, same text)."""
POLL_S = 0.02
"""Longest the UDP thread blocks while idle, so ``close()`` returns promptly."""
STREAM_POLL_S = 0.001
PACE_SLICE_S = 0.001
"""With a pace set, a burst is released in slices of this much simulated time."""
MAX_STREAM_CATCH_UP = 256
"""Records sent at once while streaming; after a longer host stall the schedule skips ahead."""
JOIN_TIMEOUT_S = 2.0


@dataclass
class EmulatorStats:
    """What the emulator did (counts)."""

    requests: int = 0
    rejected: int = 0
    """Requests ignored: wrong size, wrong header or unknown command."""
    rejected_by_reason: Counter[str] = field(default_factory=Counter)
    """The same, by reason: ``REQUEST_SIZE``, ``REQUEST_HEADER``, ``COMMAND``."""
    records_generated: int = 0
    records_sent: int = 0
    datagrams_sent: int = 0
    bias_commands: int = 0
    reboots: int = 0
    calinfo_requests: int = 0
    http_requests: int = 0
    faults: FaultCounts = field(default_factory=FaultCounts)


class NetFtEmulator(Emulator):
    """An emulated Net F/T box serving on 127.0.0.1.

    Args:
        physics: the shared cell; each record reads ``physics.true_wrench()``.
        clock: the cell's simulated clock (default: a new one, as fast as possible).
        model: the transducer and calibration (counts per unit, units, noise...).
        faults: wire faults; change them at run time with :meth:`set_faults`.
        seed: seed of the emulator's ``numpy.random.Generator``.
        rdt_port, tcp_port: None = the box's port (49152, 49151) where free, else
            any free one; 0 = any free port; else exactly that port.
        http_port: the web server's port (0 = any free one; a box uses 80).
        rdt_rate_hz: the RDT output rate (``comrdtrate``), records/s, at most 7000.
        rdt_buffer_size: records per datagram of buffered streaming (``comrdtbsiz``, 1..40).
        filter_index: the low-pass selection reported (``setuserfilter``; not modelled).
        records_hook: called with each request's records after the faults.
        on_send: called with each record just before it is sent (benchmarks time it).
    """

    def __init__(
        self,
        physics: CellPhysics,
        clock: SimClock | None = None,
        *,
        model: NetFtModelParams | None = None,
        faults: NetFtFaults | None = None,
        seed: int | None = 0,
        rdt_port: int | None = None,
        tcp_port: int | None = None,
        http_port: int = 0,
        rdt_rate_hz: float = DEFAULT_RDT_RATE_HZ,
        rdt_buffer_size: int = 1,
        filter_index: int = 0,
        records_hook: RecordsHook | None = None,
        on_send: Callable[[Record], None] | None = None,
    ) -> None:
        if not 0 < rdt_rate_hz <= MAX_RDT_RATE_HZ:
            raise ValueError(f"rdt_rate_hz={rdt_rate_hz} must be in (0, {MAX_RDT_RATE_HZ:g}]: "
                             "the Net F/T streams at most 7000 records/s")
        if not 1 <= rdt_buffer_size <= protocol.MAX_RECORDS_PER_DATAGRAM:
            raise ValueError(f"rdt_buffer_size={rdt_buffer_size} must be in "
                             f"1..{protocol.MAX_RECORDS_PER_DATAGRAM} (the box's comrdtbsiz)")
        self.physics = physics
        self.clock = clock or SimClock()
        self.params = model or NetFtModelParams()
        self.faults = faults or NetFtFaults()
        self.records_hook = records_hook
        self.on_send = on_send
        self.rdt_rate_hz = float(rdt_rate_hz)
        self.rdt_buffer_size = int(rdt_buffer_size)
        self.filter_index = filter_index
        self.rng = np.random.default_rng(seed)
        self.model = NetFtSensorModel(self.params, self.rng)
        self.stats = EmulatorStats()
        self.ft_sequence = 0
        self.boot_s = 0.0
        """Simulated time of the last (re)boot; ``ft_sequence`` counts internal samples since
        (:data:`INTERNAL_SAMPLE_RATE_HZ`)."""
        self.last_sample_s: float | None = None
        self._records_since_boot = 0
        self._lock = threading.RLock()
        self._handled = threading.Condition(self._lock)
        self._datagrams_handled = 0
        self._stream_to: tuple[str, int] | None = None
        self._stream_wall0 = 0.0
        self._stream_t0 = 0.0
        self._stream_sent = 0
        self._stream_batch = 1
        self._local: dict[tuple[str, int], Callable[[bytes], None]] = {}  # .in_process clients
        force_code, torque_code = protocol.unit_codes(self.params.force_unit,
                                                      self.params.torque_unit)
        self.calinfo = protocol.CalInfo(force_code, torque_code, self.params.counts_per_force,
                                        self.params.counts_per_torque)
        """What READCALINFO answers (a test may replace it with nonsense)."""
        self.xml_fields = settings_fields(self.params, rdt_rate_hz=self.rdt_rate_hz,
                                          filter_index=filter_index,
                                          rdt_buffer_size=self.rdt_buffer_size,
                                          internal_rate_hz=INTERNAL_SAMPLE_RATE_HZ)
        """The elements of netftapi2.xml (a test may change them)."""
        self.calibration_fields = calibration_fields(self.params)
        """The elements of netftcalapi.xml, root ``netftCalibration`` (a test may change them)."""
        self._udp = bind_loopback(socket.SOCK_DGRAM, rdt_port, protocol.RDT_PORT)
        self._tcp = CalInfoServer(
            bind_loopback(socket.SOCK_STREAM, tcp_port, protocol.CALIBRATION_TCP_PORT), self)
        self._http = XmlServer(http_port, self)
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._serve_udp, name="netft-emulator-udp", daemon=True),
            threading.Thread(target=self._tcp.serve_forever, args=(POLL_S,),
                             name="netft-emulator-tcp", daemon=True),
            threading.Thread(target=self._http.serve_forever, args=(POLL_S,),
                             name="netft-emulator-http", daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        self._mark_started()  # serving from construction (forcelearn.emulators.lifecycle)

    # ---- addresses ------------------------------------------------------
    @property
    def address(self) -> str:
        """``127.0.0.1:RDT_PORT``: the box's host and UDP stream port."""
        return f"{HOST}:{self.ports['rdt_port']}"

    @property
    def host(self) -> str:
        """Where every server listens (always loopback)."""
        return HOST

    @property
    def ports(self) -> dict[str, int]:
        """The bound ports: ``rdt_port`` (UDP), ``tcp_port`` (READCALINFO), ``http_port``."""
        return {"rdt_port": self._udp.getsockname()[1],
                "tcp_port": self._tcp.server_address[1],
                "http_port": self._http.server_address[1]}

    @property
    def streaming(self) -> bool:
        """True while a "start streaming" with sample count 0 runs (until a stop or a new start)."""
        with self._lock:
            return self._stream_to is not None

    # ---- public control -------------------------------------------------
    def set_faults(self, faults: NetFtFaults) -> None:
        """Change the wire faults now."""
        with self._lock:
            self.faults = faults

    def inject_reboot(self) -> None:
        """Reboot now: streaming stops, ``ft_sequence`` restarts, the software bias is lost."""
        with self._lock:
            self._reboot()

    def attach(self, address: tuple[str, int], deliver: Callable[[bytes], None]) -> None:
        """Hand the datagrams for ``address`` to ``deliver``, not UDP (an in-process client)."""
        with self._lock:
            self._local[address] = deliver

    def detach(self, address: tuple[str, int]) -> None:
        """Forget an in-process client (a stream to it stops)."""
        with self._lock:
            self._local.pop(address, None)
            if self._stream_to == address:
                self._stream_to = None

    def take(self, data: bytes, address: tuple[str, int]) -> None:
        """Handle one request datagram from ``address`` now, as the UDP thread would."""
        self._handle(data, address)

    def streaming_to(self, address: tuple[str, int]) -> bool:
        """True while a stream (sample count 0) to ``address`` runs."""
        return self._stream_to == address

    def netftapi2_xml(self) -> bytes:
        """The body of ``/netftapi2.xml`` from :attr:`xml_fields`."""
        return xml_page("netft", self.xml_fields)

    def netftcalapi_xml(self) -> bytes:
        """The body of ``/netftcalapi.xml`` from :attr:`calibration_fields`."""
        return xml_page("netftCalibration", self.calibration_fields)

    def state_dict(self) -> dict[str, Any]:
        """What a bit-identical resume needs: model (rng, biases), sequences, last sample time."""
        with self._lock:
            return {"model": self.model.state_dict(), "ft_sequence": self.ft_sequence,
                    "boot_s": self.boot_s, "last_sample_s": self.last_sample_s,
                    "records_since_boot": self._records_since_boot}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        with self._lock:
            self.model.load_state_dict(state["model"])
            self.ft_sequence = int(state["ft_sequence"])
            self.boot_s = float(state["boot_s"])
            last = state["last_sample_s"]
            self.last_sample_s = None if last is None else float(last)
            self._records_since_boot = int(state["records_since_boot"])

    def _release(self) -> None:
        """Stop every server and join the threads."""
        self._stop.set()
        self._tcp.shutdown()
        self._http.shutdown()
        for thread in self._threads:
            thread.join(JOIN_TIMEOUT_S)
            if thread.is_alive():
                log.warning("%s did not stop within %.1f s", thread.name, JOIN_TIMEOUT_S)
        self._udp.close()
        self._tcp.server_close()
        self._http.server_close()

    # ---- UDP ------------------------------------------------------------
    def _serve_udp(self) -> None:
        while not self._stop.is_set():
            self._udp.settimeout(STREAM_POLL_S if self._stream_to else POLL_S)
            try:
                data, address = self._udp.recvfrom(2048)
            except TimeoutError:
                data, address = b"", None
            except OSError:
                if not self._stop.is_set():
                    log.exception("netft emulator: UDP receive failed; stopping")
                return
            if address is not None:
                self._handle(data, address)
            if self._stream_to is not None:
                self._stream_due()

    def _handle(self, data: bytes, address: tuple[str, int]) -> None:
        with self._lock:
            try:
                self._handle_locked(data, address)
            finally:
                self._datagrams_handled += 1
                self._handled.notify_all()

    def wait_handled(self, datagrams: int, timeout_s: float = 2.0) -> bool:
        """Wait until ``datagrams`` UDP requests (valid or not) have been handled.

        A request needs no answer (set bias) and is handled in the emulator's
        thread whenever it gets to it; a resume restores the emulator's state
        only once what the driver sent before has taken effect, so the restored
        state is never overwritten by it (the host's speed must not decide).
        """
        with self._handled:
            return self._handled.wait_for(lambda: self._datagrams_handled >= datagrams, timeout_s)

    def _handle_locked(self, data: bytes, address: tuple[str, int]) -> None:
        request = protocol.decode_request(data)
        if isinstance(request, protocol.Rejected):
            self._reject(request.reason)
            return
        self.stats.requests += 1
        if request.command == Command.SET_BIAS:
            self.stats.bias_commands += 1
            self.model.set_software_bias(self.physics.true_wrench())
            return
        if request.command == Command.RESET_THRESHOLD_LATCH:
            return  # no thresholds are modelled, so no latch to reset
        if request.command not in (Command.STOP, Command.START_REALTIME, Command.START_BUFFERED):
            self._reject("COMMAND")  # not a command the box knows: ignored, a stream goes on
            return
        self._stream_to = None  # stop, or a new start that takes precedence over the last
        if request.command == Command.STOP:
            return
        batch = self.rdt_buffer_size if request.command == Command.START_BUFFERED else 1
        if request.sample_count == 0:
            self._stream_to = address
            self._stream_wall0 = time.monotonic()
            self._stream_t0 = self._next_sample_time()
            self._stream_sent = 0
            self._stream_batch = batch
            return
        records, times = self._generate(1, request.sample_count, self._next_sample_time())
        self._send(records, times, address, pace=True, batch=batch)

    def _reject(self, reason: str) -> None:
        """Ignore a request the box does not recognise, and count it."""
        self.stats.rejected += 1
        self.stats.rejected_by_reason[reason] += 1
        log.debug("netft emulator: request ignored (%s)", reason)

    def _stream_due(self) -> None:
        period = 1.0 / self.rdt_rate_hz
        with self._lock:
            if self._stream_to is None:
                return
            address = self._stream_to
            batch = self._stream_batch
            due = int((time.monotonic() - self._stream_wall0) * self.rdt_rate_hz) + 1
            if due - self._stream_sent > MAX_STREAM_CATCH_UP:  # never burst after a stall
                self._stream_sent = due - MAX_STREAM_CATCH_UP
            n = due - self._stream_sent
            n -= n % batch  # a buffered datagram leaves when its last record is sampled
            if n <= 0:
                return
            first = self._stream_sent + 1
            records, times = self._generate(first, n, self._stream_t0 + (first - 1) * period)
            self._stream_sent += n
        self._send(records, times, address, pace=False, batch=batch)

    def _next_sample_time(self) -> float:
        now = self.clock.now_s
        if self.last_sample_s is None:
            return now
        return max(now, self.last_sample_s + 1.0 / self.rdt_rate_hz)

    def _generate(self, first_seq: int, n: int, t0: float) -> tuple[list[Record], dict[int, float]]:
        """Sample ``n`` records (sequence ``first_seq``...) from ``t0``; apply the faults."""
        period = 1.0 / self.rdt_rate_hz
        advance = getattr(self.physics, "advance_to", None)
        times: dict[int, float] = {}
        wrenches, dts, ft_sequences, reboot = [], [], [], False
        for i in range(n):  # the physics sample by sample; the sensor model after, in one pass
            if self.faults.silent:
                break
            t = t0 + i * period
            if advance is not None:
                advance(t)
            dts.append(0.0 if self.last_sample_s is None else t - self.last_sample_s)
            wrenches.append(self.physics.true_wrench())
            self.last_sample_s = t
            # the box samples at its internal rate (7000/s) streaming or not, whatever the RDT rate
            ft = round((t - self.boot_s) * INTERNAL_SAMPLE_RATE_HZ)
            self.ft_sequence = ft % protocol.SEQUENCE_MODULUS
            ft_sequences.append(self.ft_sequence)
            times[first_seq + i] = t
            self.stats.records_generated += 1
            self._records_since_boot += 1
            limit = self.faults.reboot_after_records
            if limit is not None and self._records_since_boot >= limit:
                reboot = True
                break
        counts = self.model.measure_many(wrenches, dts)
        records = [Record(first_seq + i, ft_sequences[i], self.faults.status, counts[i])
                   for i in range(len(counts))]
        if reboot:  # after the last record's measurement, as the box's counts came first
            self._reboot()
        out = apply_faults(records, self.faults, self.rng, self.stats.faults)
        if self.records_hook is not None:
            out = self.records_hook(out)
        if records:
            times[0] = times[records[-1].rdt_sequence]  # the clock's end: the last sampled
        return out, times

    def _send(self, records: list[Record], times: dict[int, float],
              address: tuple[str, int], *, pace: bool, batch: int = 1) -> None:
        """Send ``records`` ``batch`` to a datagram, each when its last record is sampled."""
        if not times:
            return
        paced = pace and self.clock.time_scale > 0
        held_at = -1.0
        if not paced:
            self.clock.advance_to(times[0])
            if pace:
                self.clock.hold()
        for start in range(0, len(records), batch):
            datagram = records[start:start + batch]
            t = times.get(datagram[-1].rdt_sequence, times[0])
            if paced and t - held_at >= PACE_SLICE_S:
                self.clock.advance_to(t)
                self.clock.hold()
                held_at = t
            if self.on_send is not None:
                for record in datagram:
                    self.on_send(record)
            try:
                data = protocol.encode_datagram(datagram)
                local = self._local.get(address)
                if local is None:
                    self._udp.sendto(data, address)
                else:
                    local(data)
            except OSError:
                log.debug("netft emulator: send to %s failed", address, exc_info=True)
                continue
            self.stats.records_sent += len(datagram)
            self.stats.datagrams_sent += 1
        if paced:
            self.clock.advance_to(times[0])

    def _reboot(self) -> None:
        self.stats.reboots += 1
        self._stream_to = None
        self.ft_sequence = 0
        self.boot_s = self.clock.now_s if self.last_sample_s is None else max(
            self.clock.now_s, self.last_sample_s)
        self._records_since_boot = 0
        self.model.power_cycle()
        log.info("netft emulator: rebooted")


def start_emulated_netft(physics: CellPhysics, clock: SimClock | None = None, seed: int = 0,
                         **options: Any) -> NetFtEmulator:
    """Start an emulated Net F/T on loopback (the factory the emulated cell will call).

    ``options`` are :class:`NetFtEmulator`'s keywords (model, faults, ports, rate...).
    Connect a driver with ``NetFtConfig(host=emulator.host, **emulator.ports)``.
    """
    return NetFtEmulator(physics, clock, seed=seed, **options)
