"""The ATI Net F/T over Ethernet: RDT records over UDP, calibration over TCP or HTTP.

Satisfies :class:`forcelearn.devices.ForceSensor` and ``BatchForceSensor``.
Two ways to read (``NetFtConfig.mode``):

* **burst** (default): each :meth:`NetFtSensor.read_many` sends "start
  real-time streaming" with a sample count N (at most ``burst_records``); the
  box sends N records and stops. The driver receives in the caller's thread
  until record N is in, or until ``stale_timeout_s`` passes without a record
  (the tail was lost), then asks for the rest. :meth:`read` is one burst of 1.
* **stream**: one request with sample count 0 (until stopped); :meth:`read`
  returns the newest record received, :meth:`read_many` the next ``count``.

Initialisation (:meth:`initialise`; :meth:`~NetFtSensor.open` and entering
``with`` unless done; the first read):
read the calibration from the box (HTTP ``/netftapi2.xml`` or TCP
READCALINFO), refuse it if a configured value disagrees (both numbers in the
message), optionally send "set software bias", and in stream mode start
streaming. :meth:`close` sends stop and is idempotent
(:mod:`forcelearn.drivers.lifecycle`).

Every record goes through :class:`~.sequence.SequenceTracker` (lost,
duplicated, out-of-order; a reboot when ``ft_sequence`` goes back),
:class:`~.uptime.UptimeCheck` (a reboot when ``ft_sequence`` grew less than
the host's clock since the last record or the bias: the reboots the first
misses) and the status check. ``WrenchSample.counter`` is the host's stream position modulo
65536 (one step per record asked for), so the force filter sees a lost
record as a counter gap, as with the JR3.

A reboot (``ft_sequence`` goes back) after the first initialisation is
never answered by biasing here: the tool may be in contact, and a bias taken
there hides the contact force. Every read raises
:class:`~forcelearn.errors.SensorRebooted` until the cell, with the tool in
free space, calls :meth:`NetFtSensor.reinitialise` (calibration read again,
no bias) and biases (:func:`forcelearn.cell.retract_and_retare`).

Errors: :class:`SensorStale` (no record within ``stale_timeout_s`` twice),
:class:`SensorRebooted` (the box rebooted), :class:`SensorFault` (status bits set),
:class:`SensorProtocolError` (nonsense calibration), :class:`SensorBusError`
(socket errors, converted with ``raise ... from``), ``ConfigError`` (the box
disagrees with the configuration).
"""

from __future__ import annotations

import logging
import socket
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from forcelearn.devices import WrenchSample
from forcelearn.drivers.lifecycle import Driver, opened
from forcelearn.drivers.netft.calibration import (
    Calibration,
    read_calibration_http,
    read_calibration_tcp,
)
from forcelearn.drivers.netft.config import NetFtConfig
from forcelearn.drivers.netft.sequence import SequenceTracker, Verdict
from forcelearn.drivers.netft.traffic_log import TrafficLog
from forcelearn.drivers.netft.uptime import UptimeCheck
from forcelearn.errors import (
    ConfigError,
    SensorBusError,
    SensorError,
    SensorFault,
    SensorRebooted,
    SensorStale,
)
from forcelearn.protocols import netft as protocol

log = logging.getLogger(__name__)

SampleCallback = Callable[[WrenchSample], None]
COUNTER_MODULUS = 1 << 16
RECV_SIZE = 2048
SEQUENCE_BEYOND_REQUEST = "RDT_SEQUENCE_BEYOND_REQUEST"
"""``stats.rejected``'s reason for a record numbered past its request's count (damage)."""
"""Receive buffer per datagram: larger than a record, so an oversized datagram is seen whole."""
RCVBUF_BYTES = 1 << 20
"""Requested socket receive buffer; the kernel may cap it (net.core.rmem_max)."""
_NOT_SATURATED = (False,) * 6


class RdtSocket(Protocol):
    """What the driver reads RDT through: a connected UDP socket or an in-process end."""

    def send(self, data: bytes, /) -> int: ...  # noqa: D102
    def recv(self, bufsize: int, /) -> bytes: ...  # noqa: D102
    def settimeout(self, value: float | None, /) -> None: ...  # noqa: D102
    def close(self) -> None: ...  # noqa: D102


@dataclass
class NetFtStats:
    """What the driver received and sent (a snapshot copy is handed out)."""

    requests: int = 0
    datagrams: int = 0
    records: int = 0
    lost: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    reboots: int = 0
    stale_drained: int = 0
    status_errors: int = 0
    rejected: Counter[str] = field(default_factory=Counter)

    @property
    def rejected_total(self) -> int:
        """All malformed datagrams, whatever the reason."""
        return sum(self.rejected.values())


class NetFtSensor(Driver):
    """An ATI Net F/T box reached over UDP (RDT) and TCP or HTTP (calibration).

    Args:
        config: address, ports, calibration source and expectations, timeouts, log.
        on_sample: called with every delivered sample (in the reading thread).
        clock: the time the box's samples follow, s (the host's monotonic clock for a
            real box, an emulated box's simulated clock): with one, the uptime check
            (:mod:`.uptime`) sees reboots the sequence does not; None: no uptime check.
        sock: the RDT end to use instead of a UDP socket to ``config.host``
            (an emulated box's in-process end); the driver closes it.
    """

    def __init__(self, config: NetFtConfig | None = None, *,
                 on_sample: SampleCallback | None = None,
                 clock: Callable[[], float] | None = None,
                 sock: RdtSocket | None = None) -> None:
        self.config = config or NetFtConfig()
        self.callbacks: list[SampleCallback] = [on_sample] if on_sample else []
        self._tracker = SequenceTracker()
        self._uptime = UptimeCheck()
        self._clock = clock or _no_clock
        self._request_s = 0.0
        self._stats = NetFtStats()
        self._calibration: Calibration | None = None
        self._scale = np.ones(6)
        self._limits: np.ndarray | None = None
        self._position = 0  # host stream position: records asked for so far
        self._streaming = False
        self._rebooted = False
        self._requested = 0
        """Records the last finite request asked for (its records are numbered 1..this)."""
        self._log = TrafficLog(self.config.log_path) if self.config.log_path else None
        self._sock = sock if sock is not None else self._open_udp()
        self._acquired = True

    def _open_udp(self) -> socket.socket:
        sock: socket.socket | None = None
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF_BYTES)
            except OSError:  # pragma: no cover - a platform without the option
                log.debug("could not enlarge the UDP receive buffer")
            sock.connect((self.config.host, self.config.rdt_port))
        except OSError as exc:
            if sock is not None:
                sock.close()
            if self._log is not None:
                self._log.close()
            raise SensorBusError(
                f"cannot open UDP to the Net F/T at {self.config.host}:{self.config.rdt_port}: "
                f"{exc}; check the host's network settings"
            ) from exc
        return sock

    # ---- properties -----------------------------------------------------
    @property
    def calibration(self) -> Calibration | None:
        """The calibration in use, once initialised."""
        return self._calibration

    @property
    def stats(self) -> NetFtStats:
        """A snapshot of the receive counts."""
        t = self._tracker
        s = self._stats
        return NetFtStats(s.requests, s.datagrams, t.records, t.lost, t.duplicates,
                          t.out_of_order, t.reboots + self._uptime.restarts, s.stale_drained,
                          s.status_errors, Counter(s.rejected))

    # ---- commands -------------------------------------------------------
    def initialise(self) -> None:
        """Read and check the calibration, bias if configured, start streaming in stream mode."""
        self._initialise(bias=self.config.zero_on_init)

    def reinitialise(self) -> None:
        """After :class:`SensorRebooted`, with the tool in free space: initialise, no bias.

        The box reads its raw bias until the caller biases it (:meth:`zero_offsets`).
        """
        self._initialise(bias=False)
        self._rebooted = False

    def _initialise(self, *, bias: bool) -> None:
        self._check_open()
        cfg = self.config
        if cfg.calibration_source == "tcp":
            cal = read_calibration_tcp(cfg.host, cfg.tcp_port, cfg.connect_timeout_s)
        else:
            cal = read_calibration_http(cfg.host, cfg.http_port, cfg.connect_timeout_s)
        self._agree(cal)
        self._calibration = cal
        self._scale = cal.si_per_count
        ranges = cfg.full_scales if cfg.full_scales is not None else cal.ranges_si
        self._limits = None if ranges is None else (
            np.asarray(ranges, dtype=float) * cfg.near_saturation_fraction
        )
        if bias:
            self._set_bias()
        if cfg.mode == "stream":
            self._start(0)
        log.info("Net F/T at %s: %g counts/%s, %g counts/%s (%s), RDT rate %s Hz, filter %s",
                 cfg.host, cal.counts_per_force, cal.force_unit, cal.counts_per_torque,
                 cal.torque_unit, cal.source, cal.rdt_rate_hz, cal.filter_index)

    def zero_offsets(self) -> None:
        """Send "set software bias": the present load reads zero from now on (tool free!)."""
        self._ensure_initialised()
        self._set_bias()

    def restart_uptime_check(self) -> None:
        """Forget the box's last sample count (its clock or state was restored: a resume)."""
        self._uptime.forget()
        self._uptime.note_bias(self._clock())

    # ---- reading --------------------------------------------------------
    def read(self) -> WrenchSample:
        """Return the next fresh sample (burst: one record asked for; stream: the newest)."""
        self._ensure_initialised()
        if self.config.mode == "burst":
            return self.read_many(1)[0]
        newest: WrenchSample | None = None
        while (sample := self._receive(block=False)) is not None:
            newest = sample
        return newest if newest is not None else self._next_streamed()

    def read_many(self, count: int, window: int = 0) -> list[WrenchSample]:
        """Return ``count`` consecutive fresh samples, at most ``window`` asked for at once.

        ``window`` 0 means ``burst_records``. Lost records are skipped (counted
        in :attr:`stats`), so the samples are consecutive in time except where
        their counters show a gap.

        Raises:
            SensorStale: two requests in a row brought no record, or the box rebooted.
            SensorFault: a record's status word has an error bit set.
        """
        if count < 0 or window < 0:
            raise ValueError(f"count={count} and window={window} must be >= 0")
        self._ensure_initialised()
        if self.config.mode == "stream":
            return [self._next_streamed() for _ in range(count)]
        per_request = min(window or self.config.burst_records, self.config.burst_records)
        out: list[WrenchSample] = []
        empty_requests = 0
        while len(out) < count:
            got = self._burst(min(per_request, count - len(out)))
            out += got
            empty_requests = 0 if got else empty_requests + 1
            if empty_requests >= 2:
                raise SensorStale(
                    f"no record from the Net F/T at {self.config.host}:{self.config.rdt_port} "
                    f"for two requests ({self.config.stale_timeout_s} s each): check the box "
                    "is powered, its RDT interface enabled and the cable; stop the robot"
                )
        return out

    def _burst(self, n: int) -> list[WrenchSample]:
        """Ask for ``n`` records and return those that arrive, in order."""
        self._drain()
        base = self._position
        self._position += n
        self._start(n)
        got: list[WrenchSample] = []
        while self._tracker.last_rdt_sequence < n:
            sample = self._receive(block=True, base=base)
            if sample is None:
                break  # silence: the tail (or the request) was lost
            got.append(sample)
        tail = self._tracker.finish(n)
        if tail:
            log.debug("Net F/T: last %d record(s) of a request of %d lost", tail, n)
        return got

    def _next_streamed(self) -> WrenchSample:
        sample = self._receive(block=True)
        if sample is None:
            raise SensorStale(
                f"no record from the Net F/T at {self.config.host} within "
                f"{self.config.stale_timeout_s} s while streaming: check the box; stop the robot"
            )
        return sample

    def _receive(self, *, block: bool, base: int | None = None) -> WrenchSample | None:
        """Receive until one NEW record is delivered; None on silence (or nothing waiting)."""
        self._sock.settimeout(self.config.stale_timeout_s if block else 0.0)
        while True:
            try:
                data = self._sock.recv(RECV_SIZE)
            except (TimeoutError, BlockingIOError):
                return None
            except OSError as exc:
                raise SensorBusError(
                    f"UDP receive from the Net F/T at {self.config.host}:"
                    f"{self.config.rdt_port} failed: {exc}; is the box (or emulator) there?"
                ) from exc
            now = time.monotonic()
            self._stats.datagrams += 1
            if self._log is not None:
                self._log.write("rx", data, now)
            record = protocol.decode_record(data)
            if isinstance(record, protocol.Rejected):
                self._stats.rejected[record.reason] += 1
                log.debug("rejected datagram (%s): %s", record.reason, data.hex())
                continue
            if base is not None and record.rdt_sequence > self._requested:
                # a request of n records numbers them 1..n: no record of the box's (nor a
                # late one of the last request, numbered within it), so damage; not a sample
                self._stats.rejected[SEQUENCE_BEYOND_REQUEST] += 1
                log.debug("rejected record %d of a request of %d: %s", record.rdt_sequence,
                          self._requested, data.hex())
                continue
            acc = self._tracker.push(record.rdt_sequence, record.ft_sequence)
            if acc.verdict is not Verdict.NEW:
                log.debug("Net F/T record %d: %s", record.rdt_sequence, acc.verdict.value)
                continue
            if acc.lost_before:
                log.debug("Net F/T: %d record(s) lost before %d", acc.lost_before,
                          record.rdt_sequence)
            if acc.reboot or self._uptime.restarted(record.ft_sequence, self._request_s,
                                                    self._clock()):
                self._on_reboot()
            if record.status & self.config.status_error_mask:
                self._stats.status_errors += 1
                raise SensorFault(
                    record.status,
                    f"the Net F/T reports status 0x{record.status:08X} (record "
                    f"{record.rdt_sequence}): its readings are not to be trusted; see the "
                    "box's web page and the manual's system status code table; stop the robot",
                )
            if base is None:
                self._position += 1 + acc.lost_before
                position = self._position - 1
            else:
                position = base + record.rdt_sequence - 1
            sample = self._sample(record, now, position)
            for callback in self.callbacks:
                callback(sample)
            return sample

    def _sample(self, record: protocol.Record, now: float, position: int) -> WrenchSample:
        wrench = np.asarray(record.counts, dtype=float) * self._scale
        saturated: tuple[bool, ...] = _NOT_SATURATED
        if self._limits is not None:
            over = np.abs(wrench) >= self._limits
            if over.any():
                saturated = tuple(bool(v) for v in over)
        return WrenchSample(wrench, now, position % COUNTER_MODULUS, saturated)

    def _on_reboot(self) -> None:
        self._tracker.forget_ft()
        self._uptime.forget()
        self._rebooted = True
        self._streaming = False  # a rebooted box streams nothing until asked again
        log.warning("Net F/T at %s rebooted: software bias lost", self.config.host)
        raise self._rebooted_error()

    def _rebooted_error(self) -> SensorRebooted:
        return SensorRebooted(
            f"the Net F/T at {self.config.host} rebooted (its F/T sequence restarted): its "
            "software bias is lost, so its readings are off by the raw bias; retract to free "
            "space, then reinitialise() and bias (the run does it); check the box's power",
            lost="software bias",
        )

    # ---- plumbing -------------------------------------------------------
    def _agree(self, cal: Calibration) -> None:
        """Refuse a box whose calibration disagrees with the configured expectations."""
        cfg = self.config
        pairs = (
            ("counts_per_force", cfg.counts_per_force, cal.counts_per_force),
            ("counts_per_torque", cfg.counts_per_torque, cal.counts_per_torque),
            ("force_unit", cfg.force_unit, cal.force_unit),
            ("torque_unit", cfg.torque_unit, cal.torque_unit),
            ("rdt_rate_hz", cfg.rdt_rate_hz, cal.rdt_rate_hz),
        )
        for key, expected, reported in pairs:
            if expected is None or reported is None:
                continue
            same = (protocol.canonical_unit(expected) == protocol.canonical_unit(str(reported))
                    if isinstance(expected, str)
                    else abs(float(expected) - float(reported)) <= 1e-9 * abs(float(expected)))
            if not same:
                raise ConfigError(
                    f"sensor.{key} = {expected!r} in the config, but the Net F/T at {cfg.host} "
                    f"reports {reported!r} ({cal.source}): fix the config or the box's "
                    "settings; readings would be wrongly scaled"
                )

    def _set_bias(self) -> None:
        self._send(protocol.Request(protocol.Command.SET_BIAS, 0))
        self._uptime.note_bias(self._clock())

    def _start(self, sample_count: int) -> None:
        self._requested = sample_count
        self._tracker.new_request()
        self._request_s = self._clock()
        self._send(protocol.Request(protocol.Command.START_REALTIME, sample_count))
        self._streaming = sample_count == 0

    def _drain(self) -> None:
        """Account for and drop datagrams left over from the last request (late or repeated)."""
        self._sock.settimeout(0.0)
        while True:
            try:
                data = self._sock.recv(RECV_SIZE)
            except (BlockingIOError, TimeoutError, OSError):
                return
            self._stats.stale_drained += 1
            if self._log is not None:
                self._log.write("rx", data, time.monotonic())
            record = protocol.decode_record(data)
            if isinstance(record, protocol.Rejected):
                self._stats.rejected[record.reason] += 1
            else:  # a late or repeated record of the last request: account for it
                if self._tracker.push(record.rdt_sequence, record.ft_sequence).reboot:
                    self._on_reboot()  # the box rebooted between requests: its bias is gone

    def _send(self, request: protocol.Request) -> None:
        data = protocol.encode_request(request)
        try:
            self._sock.send(data)
        except OSError as exc:
            raise SensorBusError(
                f"cannot send to the Net F/T at {self.config.host}:{self.config.rdt_port}: "
                f"{exc}; check the network"
            ) from exc
        self._stats.requests += 1
        if self._log is not None:
            self._log.write("tx", data, time.monotonic())

    def _ensure_initialised(self) -> None:
        self._check_open()
        if self._rebooted:
            raise self._rebooted_error()
        if self._calibration is None:
            self.initialise()

    def _check_open(self) -> None:
        if self.closed:
            raise self._closed_error()

    # ---- life cycle (forcelearn.drivers.lifecycle) ------------------------
    def _is_ready(self) -> bool:
        return self._calibration is not None

    def _make_ready(self) -> None:
        self.initialise()

    def _release(self) -> None:
        """Send stop (best effort), close the socket and the log."""
        try:
            self._send(protocol.Request(protocol.Command.STOP, 0))
        except SensorBusError as exc:
            log.warning("Net F/T: stop not sent on close (%s)", exc)
        finally:
            self._sock.close()
            if self._log is not None:
                self._log.close()

    def _closed_error(self) -> SensorError:
        return SensorError(f"the Net F/T sensor at {self.config.host} is closed; "
                           "create a new one")

    def _label(self) -> str:
        return f"NetFtSensor on {self.config.host}"


def _no_clock() -> float:
    """No clock given: every time is 0, so the uptime check never judges."""
    return 0.0


def open_netft_sensor(config: NetFtConfig, *,
                      on_sample: SampleCallback | None = None) -> NetFtSensor:
    """Open and initialise a Net F/T sensor (closed again if that fails)."""
    return opened(NetFtSensor(config, on_sample=on_sample))
