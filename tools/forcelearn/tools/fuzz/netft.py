"""Fuzz targets of the Net F/T driver, over real loopback sockets (docs/fuzzing.md).

==============  ===================================================================
target          input and check
==============  ===================================================================
netft-xml       a netftapi2.xml body (fields of a real box, some replaced by odd
                values, encoding declarations, byte mutations) to
                ``parse_netftapi2``: a Calibration or SensorProtocolError
netft-http      that body behind an HTTP answer from a scripted server on
                127.0.0.1: honest or lying framing (Content-Length too long, too
                short, negative, twice, garbage; chunked, broken chunks), odd
                status lines, 101 headers, a 70 kB line, byte mutations; sent
                at once, held open, dripped a byte every 20 ms, or endless.
                ``read_calibration_http`` returns or raises a ForcelearnError
                within its ``timeout_s`` (+ 2 s, else a hang); an honest answer
                gives exactly what ``parse_netftapi2`` gives on its body
netft-tcp       a READCALINFO reply (mutated, short, long) from the scripted
                server, with the same behaviours; ``read_calibration_tcp``
                returns or raises a ForcelearnError in time, and what it accepts
                is what the reply's first 24 bytes decode to
netft-rdt       a burst of RDT datagrams from a scripted box on UDP (records
                mutated, duplicated, dropped, reordered, garbage, oversized,
                status bits, an F/T sequence that goes back) to a real
                ``NetFtSensor.read_many``: samples or a SensorError, never
                another exception, and every sample is a record the box sent
==============  ===================================================================
"""

from __future__ import annotations

import random
import socket
import threading
import time
from collections.abc import Callable
from contextlib import suppress
from typing import TYPE_CHECKING

import numpy as np

from forcelearn.errors import ForcelearnError
from forcelearn.tools.fuzz.box import Script, ScriptedServer
from forcelearn.tools.fuzz.targets import FuzzFailure, Tally, apply_mutations, random_mutations

if TYPE_CHECKING:
    from forcelearn.drivers.netft import NetFtSensor

TIMEOUT_S = 0.1
"""``timeout_s`` given to the calibration reads (short, so held and dripped inputs are cheap;
the property does not depend on it)."""
HANG_SLACK_S = 2.0
"""An input that takes longer than ``timeout_s`` plus this is a hang."""
DRIP_S = 0.02
"""Seconds between dripped bytes: each recv succeeds long before ``timeout_s``."""
ODD_VALUES = ("nan", "NaN", "inf", "-inf", "1e400", "-1e400", "-1", "0", "2.5", "", " ",
              "\u00b2", "\u0661\u0662", "\uff11", "9" * 400, "0x10", "1e-400", "1_000",
              "N", "lbf", "N-mm", "&amp;", "<![CDATA[7]]>", "1;2;3", ";;;;;;", "1e308;" * 6)
ENCODINGS = ("utf-8", "UTF-16", "latin-1", "ascii", "foo", "x-unknown", "utf-32", "cp1252",
             "utf-7", "idna", "rot13", "zlib", "base64", "hex", "bogus-\u00e9", "", "mbcs",
             "shift_jis", "utf-8-sig")
FIELDS = ("cfgcpf", "cfgcpt", "scfgfu", "scfgtu", "cfgmr", "comrdtrate", "setuserfilter")


# ---- bodies ---------------------------------------------------------------------------
def good_fields(rng: random.Random) -> dict[str, str]:
    """The fields of a plausible box."""
    from forcelearn.protocols import netft as protocol

    return {
        "prodname": "Net F/T",
        "cfgcpf": str(rng.choice((1_000_000, 1000, 50_000))),
        "cfgcpt": str(rng.choice((1_000_000, 1000, 50_000))),
        "scfgfu": rng.choice(sorted(protocol.FORCE_UNIT_SI)),
        "scfgtu": rng.choice(sorted(protocol.TORQUE_UNIT_SI)),
        "cfgmr": ";".join(str(rng.choice((130, 400, 10, 5000))) for _ in range(6)),
        "comrdtrate": str(rng.choice((7000, 1000, 100))),
        "setuserfilter": str(rng.randrange(9)),
    }


def xml_body(rng: random.Random) -> bytes:
    """A netftapi2.xml body, damaged in one or more ways about 80 % of the time."""
    fields = good_fields(rng)
    if rng.random() < 0.5:
        for key in rng.sample(FIELDS, rng.randint(1, 2)):
            fields[key] = rng.choice(ODD_VALUES)
    if rng.random() < 0.05:
        del fields[rng.choice(FIELDS)]
    inner = "".join(f"<{k}>{v}</{k}>" for k, v in fields.items())
    if rng.random() < 0.05:
        inner = inner * rng.randint(2, 3)
    head = ""
    if rng.random() < 0.25:
        head = f"<?xml version='1.0' encoding='{rng.choice(ENCODINGS)}'?>"
    text = f"{head}<netft>{inner}</netft>"
    try:
        body = text.encode("utf-8")
    except UnicodeEncodeError:  # pragma: no cover - every value above is encodable
        body = text.encode("utf-8", "replace")
    if rng.random() < 0.3:
        body = apply_mutations(body, random_mutations(rng))
    return body


def _outcome(call: Callable[[], object]) -> tuple[str, object]:
    """("accepted", value) or ("rejected", "<ErrorType>: message"); foreign errors raise."""
    try:
        return "accepted", call()
    except ForcelearnError as exc:
        return "rejected", f"{type(exc).__name__}"


def check_xml(body: bytes) -> str:
    """``parse_netftapi2`` returns a Calibration or raises a ForcelearnError."""
    from forcelearn.drivers.netft.calibration import parse_netftapi2

    try:
        return _outcome(lambda: parse_netftapi2(body))[0]
    except Exception as exc:
        raise FuzzFailure(f"parse_netftapi2 raised {type(exc).__name__}: {exc} "
                          f"on {body[:120]!r}") from exc


# ---- HTTP -----------------------------------------------------------------------------
STATUS_LINES = (b"HTTP/1.1 200 OK", b"HTTP/1.0 200 OK", b"HTTP/1.1 404 Not Found",
                b"HTTP/1.1 500 Internal Server Error", b"HTTP/1.1 200", b"HTTP/2 200 OK",
                b"HTTP/1.1 99999999999999999999 OK", b"HTTP/1.1 -200 OK", b"ICY 200 OK",
                b"HTTP/1.1 2OO OK", b"", b"\x00\xff\xfe", b"HTTP/1.1 100 Continue\r\n\r\n"
                b"HTTP/1.1 200 OK", b"HTTP/1.1 301 Moved\r\nLocation: http://10.0.0.1/")
FRAMINGS = ("length", "length", "length", "none", "chunked", "long", "short", "negative",
            "garbage", "twice", "bad-chunk", "huge-chunk", "many-headers", "long-line")


def http_answer(rng: random.Random, body: bytes) -> tuple[bytes, bool]:
    """An HTTP answer carrying ``body``, and whether it is honest (framed exactly)."""
    status = STATUS_LINES[0] if rng.random() < 0.6 else rng.choice(STATUS_LINES)
    framing = rng.choice(FRAMINGS)
    headers = [b"Content-Type: text/xml"]
    payload = body
    if framing == "length":
        headers.append(b"Content-Length: %d" % len(body))
    elif framing == "chunked":
        headers.append(b"Transfer-Encoding: chunked")
        cut = rng.randint(0, len(body))
        parts = [p for p in (body[:cut], body[cut:]) if p]
        payload = b"".join(b"%x\r\n%s\r\n" % (len(p), p) for p in parts) + b"0\r\n\r\n"
    elif framing == "long":
        headers.append(b"Content-Length: %d" % (len(body) + rng.randint(1, 5000)))
    elif framing == "short":
        headers.append(b"Content-Length: %d" % rng.randint(0, max(len(body) - 1, 0)))
    elif framing == "negative":
        headers.append(b"Content-Length: -%d" % rng.randint(1, 10**6))
    elif framing == "garbage":
        headers.append(b"Content-Length: " + rng.choice((b"abc", b"1e3", b"\xff", b"", b"9" * 40)))
    elif framing == "twice":
        headers += [b"Content-Length: %d" % len(body), b"Content-Length: %d" % (len(body) + 9)]
    elif framing == "bad-chunk":
        headers.append(b"Transfer-Encoding: chunked")
        payload = rng.choice((b"zz\r\n", b"-5\r\n", b"5\r\nab", b"ffffffffffffffffffff\r\n",
                              b"%x;ext=\xff\r\n" % len(body))) + body
    elif framing == "huge-chunk":
        headers.append(b"Transfer-Encoding: chunked")
        payload = b"7fffffffffffffff\r\n" + body
    elif framing == "many-headers":
        headers += [b"X-H%d: v" % i for i in range(101)]
    elif framing == "long-line":
        headers.append(b"X-Long: " + b"a" * 70_000)
    answer = status + b"\r\n" + b"\r\n".join(headers) + b"\r\n\r\n" + payload
    honest = status == STATUS_LINES[0] and framing in ("length", "none", "chunked")
    if rng.random() < 0.15:
        answer = apply_mutations(answer, random_mutations(rng))
        honest = False
    return answer, honest


def behaviour(rng: random.Random) -> str:
    """Mostly ``close``; held, dripped and endless answers about 2 % of the time."""
    roll = rng.random()
    return ("hold" if roll < 0.005 else "drip" if roll < 0.01 else "endless" if roll < 0.02
            else "close")


def _timed(call: Callable[[], object], what: str, timeout_s: float) -> tuple[str, object]:
    """``_outcome`` of ``call``, refusing foreign exceptions and calls past their deadline."""
    started = time.monotonic()
    try:
        result = _outcome(call)
    except Exception as exc:
        raise FuzzFailure(f"{what} raised {type(exc).__name__}: {exc}") from exc
    elapsed = time.monotonic() - started
    if elapsed > timeout_s + HANG_SLACK_S:
        raise FuzzFailure(f"{what} raised a hang: {elapsed:.1f} s with timeout_s = {timeout_s}")
    return result


def check_http(server: ScriptedServer, answer: bytes, honest: bool, body: bytes,
               how: str) -> str:
    """One GET against ``answer`` served as ``how``; typed, in time, honest answers exact."""
    from forcelearn.drivers.netft.calibration import parse_netftapi2, read_calibration_http

    server.push(Script(answer, how, DRIP_S))
    got = _timed(lambda: read_calibration_http("127.0.0.1", server.port, TIMEOUT_S),
                 f"read_calibration_http ({how}) on {answer[:100]!r}", TIMEOUT_S)
    if honest and how == "close":
        expected = _outcome(lambda: parse_netftapi2(body))
        if got != expected:
            raise FuzzFailure(f"an honest answer gave {got}, its body parses to {expected}")
    return got[0]


# ---- TCP READCALINFO ------------------------------------------------------------------
def calinfo_reply(rng: random.Random) -> bytes:
    """A READCALINFO reply of a plausible box, mutated 70 % of the time (also short or long)."""
    from forcelearn.protocols import netft as protocol

    info = protocol.CalInfo(rng.choice(sorted(protocol.FORCE_UNITS)),
                            rng.choice(sorted(protocol.TORQUE_UNITS)),
                            rng.choice((1_000_000, 1000, 0, 2**32 - 1)),
                            rng.choice((1_000_000, 1000, 7)))
    reply = protocol.encode_calinfo_reply(info)
    if rng.random() < 0.7:
        reply = apply_mutations(reply, random_mutations(rng))
    return reply


def check_tcp(server: ScriptedServer, reply: bytes, how: str) -> str:
    """READCALINFO against ``reply``: typed, in time, and what is accepted is what was sent."""
    from forcelearn.drivers.netft.calibration import from_calinfo, read_calibration_tcp
    from forcelearn.errors import SensorProtocolError
    from forcelearn.protocols import netft as protocol

    server.push(Script(reply, how, DRIP_S))
    got = _timed(lambda: read_calibration_tcp("127.0.0.1", server.port, TIMEOUT_S),
                 f"read_calibration_tcp ({how}) on {reply.hex()}", TIMEOUT_S)
    size = protocol.CALINFO_REPLY.size
    if how in ("close", "endless") and (len(reply) >= size or how == "close"):
        data = (reply + b"<x>0</x>" * 4)[:size] if how == "endless" else reply[:size]

        def decode() -> object:
            info = protocol.decode_calinfo_reply(data)
            if isinstance(info, protocol.Rejected):
                raise SensorProtocolError(info.reason)
            return from_calinfo(info)

        expected = _outcome(decode)
        # The driver reads up to 25 bytes to see an overlong reply; if the 25th comes in
        # a later segment it decodes the first 24: both are right, nothing else is.
        longer = len(reply) > size or how == "endless"
        if got != expected and not (longer and got == ("rejected", "SensorProtocolError")):
            raise FuzzFailure(f"READCALINFO {reply.hex()} ({how}) gave {got}, expected "
                              f"{expected}")
    return got[0]


# ---- RDT over UDP ---------------------------------------------------------------------
class RdtBox:
    """A scripted Net F/T's RDT side on 127.0.0.1: answers each request with a queued burst.

    Without a queued burst it answers a request for k records with k clean ones, as a
    box does. Every record sent is remembered (:attr:`sent`) for the check.
    """

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.bursts: list[list[bytes]] = []
        self.sent: set[tuple[int, ...]] = set()
        """Counts of the records sent for this input and the last few (a late datagram of
        the previous burst may arrive during the next one)."""
        self.earlier: list[set[tuple[int, ...]]] = []
        self.ft = 0
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, name="fuzz-rdt", daemon=True)
        self.thread.start()

    @property
    def port(self) -> int:
        """The UDP port."""
        port: int = self.sock.getsockname()[1]
        return port

    def record(self, rdt: int, counts: tuple[int, ...], status: int = 0,
               ft: int | None = None) -> bytes:
        """An encoded record (the F/T sequence advances unless given)."""
        from forcelearn.protocols import netft as protocol

        if ft is None:
            self.ft += 1
            ft = self.ft
        return protocol.encode_record(protocol.Record(rdt, ft, status, counts))

    def _serve(self) -> None:
        from forcelearn.protocols import netft as protocol

        while not self.stop.is_set():
            try:
                data, peer = self.sock.recvfrom(2048)
            except (TimeoutError, OSError):
                continue
            request = protocol.decode_request(data)
            if isinstance(request, protocol.Rejected):
                continue
            if request.command != protocol.Command.START_REALTIME:
                continue
            with self.lock:
                burst = self.bursts.pop(0) if self.bursts else [
                    self.record(i + 1, (i, -i, 2 * i, 3, 4, 5))
                    for i in range(request.sample_count or 1)]
                for datagram in burst:
                    decoded = protocol.decode_record(datagram)
                    if not isinstance(decoded, protocol.Rejected):
                        self.sent.add(decoded.counts)
            for datagram in burst:
                with suppress(OSError):
                    self.sock.sendto(datagram, peer)

    def close(self) -> None:
        """Stop serving."""
        self.stop.set()
        self.thread.join(timeout=2)
        self.sock.close()


def rdt_burst(rng: random.Random, box: RdtBox, n: int) -> list[bytes]:
    """``n`` records of a burst, damaged: mutated, duplicated, dropped, reordered, garbage."""
    datagrams = []
    for i in range(1, n + 1):
        counts = tuple(rng.randint(-(2**31), 2**31 - 1) if rng.random() < 0.05
                       else rng.randint(-50_000, 50_000) for _ in range(6))
        status = rng.choice((1, 0x80000000)) if rng.random() < 0.01 else 0
        ft = max(box.ft - rng.randint(1, 100), 0) if rng.random() < 0.01 else None
        datagram = box.record(i, counts, status, ft)
        roll = rng.random()
        if roll < 0.1:
            datagram = apply_mutations(datagram, random_mutations(rng, 2))
        if roll > 0.97:
            continue  # lost
        datagrams.append(datagram)
        if rng.random() < 0.03:
            datagrams.append(datagram)  # duplicated
    if rng.random() < 0.1:
        datagrams.insert(rng.randint(0, len(datagrams)),
                         rng.randbytes(rng.choice((0, 1, 35, 37, 100, 1500, 3000))))
    if rng.random() < 0.05:
        rng.shuffle(datagrams)
    return datagrams


def check_rdt(sensor: NetFtSensor, box: RdtBox, burst: list[bytes], n: int) -> str:
    """``read_many(n)`` against ``burst``: samples of sent records, or a typed SensorError."""
    with box.lock:
        box.bursts = [burst]
        box.earlier = [box.sent, *box.earlier[:7]]
        box.sent = set()
    started = time.monotonic()
    try:
        samples = sensor.read_many(n)
    except ForcelearnError:
        return "rejected"
    except Exception as exc:
        raise FuzzFailure(f"NetFtSensor.read_many raised {type(exc).__name__}: {exc}") from exc
    finally:
        elapsed = time.monotonic() - started
    if elapsed > 10 * sensor.config.stale_timeout_s + HANG_SLACK_S:
        raise FuzzFailure(f"NetFtSensor.read_many raised a hang: {elapsed:.1f} s")
    scale = sensor._scale  # the driver's own counts -> SI factors
    with box.lock:
        sent = set(box.sent).union(*box.earlier)
    for sample in samples:
        counts = tuple(int(c) for c in np.rint(sample.wrench / scale))
        if counts not in sent:
            raise FuzzFailure(f"a sample {counts} matches no record the box sent")
    return "accepted"


# ---- the runs -------------------------------------------------------------------------
def run_target(target: str, rng: random.Random, inputs: int, tally: Tally) -> None:
    """Run ``inputs`` inputs of one of this module's targets into ``tally``."""
    if target == "netft-xml":
        for _ in range(inputs):
            body = xml_body(rng)
            tally.add(lambda body=body: check_xml(body))  # type: ignore[misc]
    elif target == "netft-http":
        with ScriptedServer() as server:
            for _ in range(inputs):
                body = xml_body(rng)
                answer, honest = http_answer(rng, body)
                how = behaviour(rng)
                tally.add(lambda a=answer, h=honest, b=body, w=how:  # type: ignore[misc]
                          check_http(server, a, h, b, w))
    elif target == "netft-tcp":
        with ScriptedServer() as server:
            for _ in range(inputs):
                reply, how = calinfo_reply(rng), behaviour(rng)
                tally.add(lambda r=reply, w=how: check_tcp(server, r, w))  # type: ignore[misc]
    elif target == "netft-rdt":
        _run_rdt(rng, inputs, tally)
    else:  # pragma: no cover - fuzz.py only routes this module's names here
        raise ValueError(f"unknown target {target!r}")


def _run_rdt(rng: random.Random, inputs: int, tally: Tally) -> None:
    from forcelearn.drivers.netft import NetFtConfig, NetFtSensor
    from forcelearn.protocols import netft as protocol

    box = RdtBox()
    calinfo = protocol.encode_calinfo_reply(protocol.CalInfo(2, 3, 1_000_000, 1_000_000))
    with ScriptedServer(default=Script(calinfo)) as tcp:
        config = NetFtConfig(host="127.0.0.1", rdt_port=box.port, calibration_source="tcp",
                             tcp_port=tcp.port, stale_timeout_s=0.02, connect_timeout_s=1.0)
        try:
            with NetFtSensor(config) as sensor:
                for _ in range(inputs):
                    n = rng.randint(1, 8)
                    burst = rdt_burst(rng, box, n)
                    tally.add(lambda b=burst, k=n:  # type: ignore[misc]
                              check_rdt(sensor, box, b, k))
        finally:
            box.close()


TARGETS = ("netft-xml", "netft-http", "netft-tcp", "netft-rdt")
"""The targets this module runs (registered in :mod:`forcelearn.tools.fuzz.targets`)."""
