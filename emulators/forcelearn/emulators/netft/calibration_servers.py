"""The Net F/T box's calibration side, on loopback: READCALINFO over TCP and its two XML pages.

A driver reads these once when it connects (counts per unit, units, ranges); the
record stream itself is UDP (:mod:`forcelearn.emulators.netft.server`).

* TCP (``CALIBRATION_TCP_PORT``, 49151): a 20-byte READCALINFO request gets the
  24-byte calibration reply of :attr:`ServedBox.calinfo`; anything else, nothing.
* HTTP: ``/netftapi2.xml`` (settings) and ``/netftcalapi.xml`` (calibration, root
  ``netftCalibration``); ``?index=0`` or no index selects the one configuration
  and calibration the emulated box holds, any other page or index is 404. The
  fields and their sources: docs/netft.md.

Both servers run each request in a daemon thread; a client that hangs up
mid-reply is logged, not printed as a trace.
"""

from __future__ import annotations

import contextlib
import errno
import html
import logging
import socket
import socketserver
import sys
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Protocol
from urllib.parse import parse_qs, urlsplit

from forcelearn.emulators.netft.sensor_model import NetFtModelParams
from forcelearn.protocols import netft as protocol

log = logging.getLogger(__name__)

HOST = "127.0.0.1"


class RequestCounts(Protocol):
    """The counts the servers keep (the emulator's stats)."""

    calinfo_requests: int
    http_requests: int


class ServedBox(Protocol):
    """What the servers read of the emulated box."""

    @property
    def calinfo(self) -> protocol.CalInfo:
        """What READCALINFO answers."""

    @property
    def stats(self) -> RequestCounts:
        """Where the requests are counted."""

    def netftapi2_xml(self) -> bytes:
        """The body of ``/netftapi2.xml``."""

    def netftcalapi_xml(self) -> bytes:
        """The body of ``/netftcalapi.xml``."""


def bind_loopback(kind: int, port: int | None, default: int) -> socket.socket:
    """Bind a socket on 127.0.0.1: ``port`` exactly, or None = ``default`` where free, else any."""
    sock = socket.socket(socket.AF_INET, kind)
    if kind == socket.SOCK_STREAM:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((HOST, default if port is None else port))
    except OSError as exc:
        if port is not None or exc.errno != errno.EADDRINUSE:
            sock.close()
            raise
        log.info("port %d is taken; the emulated Net F/T uses a free one", default)
        sock.bind((HOST, 0))
    return sock


class _CalInfoHandler(socketserver.BaseRequestHandler):
    def handle(self) -> None:
        box: ServedBox = self.server.box  # type: ignore[attr-defined]
        self.request.settimeout(1.0)
        data = b""
        with contextlib.suppress(OSError):
            while len(data) < protocol.CALINFO_REQUEST_SIZE:
                chunk = self.request.recv(protocol.CALINFO_REQUEST_SIZE - len(data))
                if not chunk:
                    break
                data += chunk
            if protocol.is_calinfo_request(data):
                box.stats.calinfo_requests += 1
                self.request.sendall(protocol.encode_calinfo_reply(box.calinfo))


class _XmlHandler(BaseHTTPRequestHandler):
    def do_GET(self) -> None:
        box: ServedBox = self.server.box  # type: ignore[attr-defined]
        box.stats.http_requests += 1
        url = urlsplit(self.path)
        index = parse_qs(url.query).get("index", ["0"])
        pages = {protocol.CALIBRATION_XML_PATH: box.netftapi2_xml,
                 protocol.CALIBRATION_API_XML_PATH: box.netftcalapi_xml}
        page = pages.get(url.path)
        if page is None or index != ["0"]:  # one configuration, one calibration
            self.send_error(404)
            return
        body = page()
        self.send_response(200)
        self.send_header("Content-Type", "text/xml")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("netft http: " + format, *args)


class _QuietOnHangUp:
    """A client that hangs up mid-reply (its timeout passed) is logged, not printed as a trace."""

    def handle_error(self, request: Any, client_address: Any) -> None:
        exc = sys.exc_info()[1]
        if isinstance(exc, OSError):
            log.debug("netft: client %s hung up: %s", client_address, exc)
        else:
            log.error("netft: a request from %s failed", client_address, exc_info=exc)


class CalInfoServer(_QuietOnHangUp, socketserver.ThreadingTCPServer):
    """READCALINFO over TCP on an already bound socket; ``serve_forever`` serves it."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, sock: socket.socket, box: ServedBox) -> None:
        super().__init__(sock.getsockname(), _CalInfoHandler, bind_and_activate=False)
        self.socket.close()
        self.socket = sock
        self.server_activate()
        self.box = box


class XmlServer(_QuietOnHangUp, ThreadingHTTPServer):
    """The two XML pages over HTTP on 127.0.0.1:``port`` (0: any free port)."""

    daemon_threads = True

    def __init__(self, port: int, box: ServedBox) -> None:
        super().__init__((HOST, port), _XmlHandler)
        self.box = box


def xml_page(root: str, fields: dict[str, str]) -> bytes:
    """An XML page as the box serves it: one root element, one child element per field."""
    inner = "".join(f"<{k}>{html.escape(v)}</{k}>" for k, v in fields.items())
    return f'<?xml version="1.0" encoding="utf-8"?><{root}>{inner}</{root}>'.encode()


def ranges_in_units(params: NetFtModelParams) -> list[float]:
    """The transducer's ranges in the box's force and torque units (``cfgmr``, ``calmr``)."""
    f = protocol.FORCE_UNIT_SI[params.force_unit]
    t = protocol.TORQUE_UNIT_SI[params.torque_unit]
    return [r / (f if i < 3 else t) for i, r in enumerate(params.ranges)]


def _ranges_text(params: NetFtModelParams) -> str:
    return ";".join(f"{r:g}" for r in ranges_in_units(params))


def settings_fields(params: NetFtModelParams, *, rdt_rate_hz: float, filter_index: int,
                    rdt_buffer_size: int, internal_rate_hz: float) -> dict[str, str]:
    """The elements of netftapi2.xml for a box with these settings (rates in records/s)."""
    return {
        "prodname": "forcelearn emulated Net F/T",
        "cfgcpf": str(params.counts_per_force),
        "cfgcpt": str(params.counts_per_torque),
        "scfgfu": params.force_unit,
        "scfgtu": params.torque_unit,
        "cfgmr": _ranges_text(params),
        "comrdtrate": f"{rdt_rate_hz:g}",
        "setuserfilter": str(filter_index),
        "runrate": f"{internal_rate_hz:g}",  # the internal rate, not the RDT rate
        "comrdtbsiz": str(rdt_buffer_size),
        "setcfgsel": "0",
        "cfgcalsel": "0",
    }


def calibration_fields(params: NetFtModelParams) -> dict[str, str]:
    """The elements of netftcalapi.xml (root ``netftCalibration``) for this calibration."""
    force_code, torque_code = protocol.unit_codes(params.force_unit, params.torque_unit)
    return {
        "calsn": "FT00000",
        "calpn": "forcelearn-emulated",
        "caldt": "2026/01/01",
        "calfu": str(force_code),
        "caltu": str(torque_code),
        "scalfu": params.force_unit,
        "scaltu": params.torque_unit,
        "calcpf": str(params.counts_per_force),
        "calcpt": str(params.counts_per_torque),
        "calmr": _ranges_text(params),
    }
