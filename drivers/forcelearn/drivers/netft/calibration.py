"""Counts per unit and units of a Net F/T: read from the box over TCP or HTTP, then checked.

Two sources, the same :class:`Calibration`:

* **TCP** (port 49151): the binary READCALINFO exchange of :mod:`.protocol`
  (units as codes, counts per unit as u32).
* **HTTP** ``/netftapi2.xml``: ``cfgcpf``, ``cfgcpt`` (counts per unit),
  ``scfgfu``, ``scfgtu`` (unit names), and when present ``comrdtrate`` (RDT
  output rate, Hz), ``setuserfilter`` (low-pass filter index) and ``cfgmr``
  (the six calibrated ranges, ``;``-separated, in the configured units).

Whatever the source, :func:`check_calibration` refuses values no real box
sends (zero, negative, not finite or implausible counts per unit, unknown
units, a filter index outside 0..15) with
:class:`~forcelearn.errors.SensorProtocolError`: a wrong scale would turn every
reading into a wrong force.

Nothing the box (or a host posing as it) sends escapes as a foreign exception:
a body that is not XML, declares an unknown encoding or is larger than
:data:`MAX_XML_BYTES` is a SensorProtocolError, a broken HTTP exchange a
SensorBusError, and ``timeout_s`` bounds the whole read, connection to last
byte (:mod:`.deadline`): a box dripping one byte at a time is a SensorTimeout
after ``timeout_s``, not a start-up that never ends.
"""

from __future__ import annotations

import http.client
import math
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from forcelearn.drivers.netft.deadline import DeadlineHTTPConnection, connect_by
from forcelearn.errors import SensorBusError, SensorError, SensorProtocolError, SensorTimeout
from forcelearn.protocols import netft as protocol

COUNTS_PER_UNIT_RANGE = (1.0, 1.0e8)
"""Plausible counts per force or torque unit. ATI ships 1,000,000 per unit (N, N-m or N-mm);
a value outside this range is a garbled reply, not a calibration (assumption: two decades of
margin each way below and above any ATI calibration seen)."""
RDT_RATE_RANGE_HZ = (1.0, 10_000.0)
"""RDT output rates a box can be set to (the Net F/T's maximum is 7000 Hz; Axia 7912 Hz)."""
FILTER_INDEX_RANGE = (0, 15)
"""Low-pass selections ``setuserfilter`` may name. The Net F/T manual lists 0 (no filter)
to 8; the range leaves room for firmware that adds settings, and refuses a NaN, a
fraction or a garbled number."""
MAX_XML_BYTES = 1 << 20
"""Largest ``/netftapi2.xml`` body read (bytes); the box's is about 10 kB."""
XML_ERRORS = (ET.ParseError, LookupError, ValueError)
"""What ``ElementTree.fromstring`` raises on hostile bytes: a syntax error, an unknown
encoding declaration (LookupError), bytes the declared codec cannot decode (ValueError)."""


@dataclass(frozen=True)
class Calibration:
    """What turns counts into newtons and newton-metres, and what the box said about itself.

    Attributes:
        counts_per_force: counts per ``force_unit``.
        counts_per_torque: counts per ``torque_unit``.
        force_unit: ``scfgfu`` spelling (``"N"``, ``"lbf"``...).
        torque_unit: ``scfgtu`` spelling (``"N-m"``, ``"N-mm"``...).
        rdt_rate_hz: the box's RDT output rate, if the source tells (HTTP only).
        filter_index: the box's low-pass filter selection, if the source tells.
        ranges_si: the six calibrated ranges in N and N·m, if the source tells.
        source: ``"tcp"``, ``"http"`` or ``"config"``.
    """

    counts_per_force: float
    counts_per_torque: float
    force_unit: str = "N"
    torque_unit: str = "N-m"
    rdt_rate_hz: float | None = None
    filter_index: int | None = None
    ranges_si: tuple[float, ...] | None = None
    source: str = "config"

    @property
    def si_per_count(self) -> np.ndarray:
        """Six factors: N per count (Fx, Fy, Fz), N·m per count (Tx, Ty, Tz)."""
        force = protocol.FORCE_UNIT_SI[self.force_unit] / self.counts_per_force
        torque = protocol.TORQUE_UNIT_SI[self.torque_unit] / self.counts_per_torque
        return np.array([force] * 3 + [torque] * 3)


def check_calibration(cal: Calibration) -> Calibration:
    """Return ``cal`` if every value is one a real box sends; else raise SensorProtocolError."""
    low, high = COUNTS_PER_UNIT_RANGE
    for name in ("counts_per_force", "counts_per_torque"):
        value = getattr(cal, name)
        if not (isinstance(value, int | float) and math.isfinite(value) and low <= value <= high):
            raise SensorProtocolError(
                f"the Net F/T ({cal.source}) sent {name} = {value!r}, not a plausible "
                f"calibration ({low:g}..{high:g}): check the box's configuration page, or "
                "set the value in the config after reading it on the box"
            )
    if cal.force_unit not in protocol.FORCE_UNIT_SI:
        raise SensorProtocolError(
            f"the Net F/T ({cal.source}) reports force unit {cal.force_unit!r}; "
            f"known: {sorted(protocol.FORCE_UNIT_SI)}"
        )
    if cal.torque_unit not in protocol.TORQUE_UNIT_SI:
        raise SensorProtocolError(
            f"the Net F/T ({cal.source}) reports torque unit {cal.torque_unit!r}; "
            f"known: {sorted(protocol.TORQUE_UNIT_SI)}"
        )
    if cal.rdt_rate_hz is not None:
        low, high = RDT_RATE_RANGE_HZ
        if not (math.isfinite(cal.rdt_rate_hz) and low <= cal.rdt_rate_hz <= high):
            raise SensorProtocolError(
                f"the Net F/T ({cal.source}) reports an RDT rate of {cal.rdt_rate_hz!r} Hz; "
                f"expected {low:g}..{high:g} Hz: check its communication settings page"
            )
    if cal.filter_index is not None:
        low_f, high_f = FILTER_INDEX_RANGE
        if not low_f <= cal.filter_index <= high_f:
            raise SensorProtocolError(
                f"the Net F/T ({cal.source}) reports low-pass filter index (setuserfilter) "
                f"{cal.filter_index}; expected {low_f}..{high_f}: check its settings page"
            )
    if cal.ranges_si is not None and (
        len(cal.ranges_si) != 6 or not all(math.isfinite(r) and r > 0 for r in cal.ranges_si)
    ):
        raise SensorProtocolError(
            f"the Net F/T ({cal.source}) reports calibrated ranges {cal.ranges_si!r}; "
            "expected six positive values"
        )
    return cal


def from_calinfo(info: protocol.CalInfo) -> Calibration:
    """Turn a READCALINFO reply into a checked :class:`Calibration`."""
    force = protocol.FORCE_UNITS.get(info.force_unit_code)
    torque = protocol.TORQUE_UNITS.get(info.torque_unit_code)
    if force is None or torque is None:
        raise SensorProtocolError(
            f"the Net F/T (tcp) sent unit codes force={info.force_unit_code}, "
            f"torque={info.torque_unit_code}; known force {sorted(protocol.FORCE_UNITS)}, "
            f"torque {sorted(protocol.TORQUE_UNITS)}"
        )
    return check_calibration(Calibration(
        float(info.counts_per_force), float(info.counts_per_torque), force[0], torque[0],
        source="tcp",
    ))


def parse_netftapi2(xml: bytes) -> Calibration:
    """Parse ``/netftapi2.xml`` into a checked :class:`Calibration` (pure)."""
    try:
        root = ET.fromstring(xml)
    except XML_ERRORS as exc:
        raise SensorProtocolError(
            f"the Net F/T's netftapi2.xml is not XML ({type(exc).__name__}: {exc}): "
            "is this a Net F/T's web server?"
        ) from exc

    def text(tag: str, required: bool = True) -> str | None:
        node = root.find(f".//{tag}")
        if node is None or node.text is None:
            if required:
                raise SensorProtocolError(f"the Net F/T's netftapi2.xml has no <{tag}>")
            return None
        return node.text.strip()

    def number(tag: str, required: bool = True) -> float | None:
        raw = text(tag, required)
        if raw is None:
            return None
        try:
            return float(raw)
        except ValueError as exc:
            raise SensorProtocolError(
                f"the Net F/T's netftapi2.xml <{tag}> is {raw!r}, not a number"
            ) from exc

    def index(tag: str) -> int | None:
        value = number(tag, required=False)
        if value is None:
            return None
        if not (math.isfinite(value) and value.is_integer()
                and FILTER_INDEX_RANGE[0] <= value <= FILTER_INDEX_RANGE[1]):
            raise SensorProtocolError(
                f"the Net F/T's netftapi2.xml <{tag}> is {value!r}, not a filter index "
                f"{FILTER_INDEX_RANGE[0]}..{FILTER_INDEX_RANGE[1]}"
            )
        return int(value)

    force_unit, torque_unit = text("scfgfu"), text("scfgtu")
    rate = number("comrdtrate", required=False)
    filt = index("setuserfilter")
    ranges_si = None
    raw_ranges = text("cfgmr", required=False)
    if raw_ranges is not None and force_unit in protocol.FORCE_UNIT_SI and (
        torque_unit in protocol.TORQUE_UNIT_SI
    ):
        try:
            ranges = [float(v) for v in raw_ranges.split(";") if v.strip()]
        except ValueError as exc:
            raise SensorProtocolError(f"netftapi2.xml <cfgmr> is {raw_ranges!r}") from exc
        f_si = protocol.FORCE_UNIT_SI[force_unit]
        t_si = protocol.TORQUE_UNIT_SI[torque_unit]
        ranges_si = tuple(r * (f_si if i < 3 else t_si) for i, r in enumerate(ranges))
    return check_calibration(Calibration(
        number("cfgcpf"), number("cfgcpt"), force_unit, torque_unit,  # type: ignore[arg-type]
        rdt_rate_hz=rate, filter_index=filt,
        ranges_si=ranges_si, source="http",
    ))


def read_calibration_tcp(host: str, port: int, timeout_s: float) -> Calibration:
    """Ask the box for READCALINFO over TCP; return the checked calibration.

    ``timeout_s`` bounds the whole exchange (connect, request, reply).
    """
    deadline = time.monotonic() + timeout_s
    try:
        with connect_by(host, port, deadline) as sock:
            sock.sendall(protocol.encode_calinfo_request())
            reply = b""
            while len(reply) < protocol.CALINFO_REPLY.size:
                chunk = sock.recv(protocol.CALINFO_REPLY.size + 1 - len(reply))
                if not chunk:
                    break
                reply += chunk
    except TimeoutError as exc:
        raise SensorTimeout(
            f"no complete READCALINFO reply from the Net F/T at {host}:{port} within "
            f"{timeout_s} s: check its IP address, cable and power"
        ) from exc
    except (OSError, UnicodeError) as exc:
        raise SensorBusError(
            f"cannot read the Net F/T's calibration over TCP at {host}:{port}: {exc}; "
            "check the IP address and that the box is powered"
        ) from exc
    info = protocol.decode_calinfo_reply(reply)
    if isinstance(info, protocol.Rejected):
        raise SensorProtocolError(
            f"the Net F/T at {host}:{port} answered READCALINFO with {len(reply)} bytes "
            f"({info.reason}): {reply.hex()}; is this a Net F/T?"
        )
    return from_calinfo(info)


def read_calibration_http(host: str, port: int, timeout_s: float,
                          path: str = protocol.CALIBRATION_XML_PATH) -> Calibration:
    """GET ``/netftapi2.xml`` from the box; return the checked calibration.

    ``timeout_s`` bounds the whole exchange, connection to last byte; a body
    over :data:`MAX_XML_BYTES` is refused.
    """
    deadline = time.monotonic() + timeout_s
    where = f"GET {path} from the Net F/T at {host}:{port}"
    conn = DeadlineHTTPConnection(host, port, deadline)
    try:
        conn.request("GET", path)
        response = conn.getresponse()
        status = response.status
        body = response.read(MAX_XML_BYTES + 1)
        # http.client's read(amt) returns a short body quietly when the server closes
        # early; ``length`` is what the Content-Length announced and never came.
        missing = response.length if len(body) <= MAX_XML_BYTES else None
    except TimeoutError as exc:
        raise SensorTimeout(
            f"no complete answer to {where} within {timeout_s} s: check its IP address, "
            "and that nothing else answers on that port"
        ) from exc
    except (OSError, http.client.HTTPException, ValueError, OverflowError) as exc:
        raise SensorBusError(
            f"cannot {where}: {type(exc).__name__}: {exc}; check the IP address, and that "
            "the web server is on"
        ) from exc
    finally:
        conn.close()
    if status != 200:
        raise SensorError(f"the Net F/T at {host}:{port} answered GET {path} with HTTP {status}")
    if len(body) > MAX_XML_BYTES:
        raise SensorProtocolError(
            f"the answer to {where} is larger than {MAX_XML_BYTES} bytes; a Net F/T's "
            "netftapi2.xml is about 10 kB: is this a Net F/T?"
        )
    if missing:
        raise SensorBusError(
            f"the answer to {where} ended {missing} bytes short of its Content-Length: "
            "the connection broke, or this is not a Net F/T"
        )
    return parse_netftapi2(body)
