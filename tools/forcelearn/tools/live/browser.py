"""Headless Chromium over the DevTools protocol, with no driver library (tests, screenshots).

``python -m forcelearn.tools.live.browser URL OUT.png`` opens a live page,
waits until its plots are drawn and its trial number has advanced, and
saves a screenshot (how docs/results/live_*.png are made).

The DevTools protocol is JSON over a WebSocket; the small client below
speaks just enough of RFC 6455 for it (text frames, masked from the client,
ping, close). Chromium is found as ``$FORCELEARN_CHROMIUM``, ``chromium``,
``chromium-browser``, ``google-chrome`` or ``headless_shell`` on PATH.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import queue
import shutil
import socket
import struct
import subprocess
import tempfile
import threading
import urllib.request
from pathlib import Path
from types import TracebackType
from typing import Any
from urllib.parse import urlsplit

NAMES = ("chromium", "chromium-browser", "google-chrome", "headless_shell")


class BrowserError(RuntimeError):
    """Chromium did not start, or the DevTools protocol answered with an error."""


def find_chromium() -> str | None:
    """The path of a Chromium to run, or None."""
    named = os.environ.get("FORCELEARN_CHROMIUM")
    if named:
        return shutil.which(named) or (named if Path(named).exists() else None)
    return next((path for name in NAMES if (path := shutil.which(name))), None)


class _WebSocket:
    """A minimal client WebSocket (RFC 6455) for the DevTools protocol."""

    def __init__(self, url: str, timeout_s: float):
        parts = urlsplit(url)
        self._sock = socket.create_connection((parts.hostname, parts.port), timeout=timeout_s)
        key = base64.b64encode(os.urandom(16)).decode()
        request = (
            f"GET {parts.path} HTTP/1.1\r\nHost: {parts.netloc}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
        )
        self._sock.sendall(request.encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self._sock.recv(1)
            if not chunk:
                raise BrowserError("DevTools closed the WebSocket handshake")
            head += chunk
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise BrowserError(f"DevTools refused the WebSocket: {head[:80]!r}")

    def _exact(self, count: int) -> bytes:
        data = b""
        while len(data) < count:
            chunk = self._sock.recv(count - len(data))
            if not chunk:
                raise BrowserError("DevTools closed the WebSocket")
            data += chunk
        return data

    def _send(self, opcode: int, payload: bytes) -> None:
        size = len(payload)
        header = bytes([0x80 | opcode])
        if size < 126:
            header += bytes([0x80 | size])
        elif size < 1 << 16:
            header += bytes([0x80 | 126]) + struct.pack(">H", size)
        else:
            header += bytes([0x80 | 127]) + struct.pack(">Q", size)
        mask = os.urandom(4)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        self._sock.sendall(header + mask + masked)

    def send_text(self, text: str) -> None:
        """Send one text message."""
        self._send(0x1, text.encode())

    def recv_text(self) -> str:
        """Receive one whole text message (answering pings)."""
        message = b""
        while True:
            first, second = self._exact(2)
            opcode, size = first & 0x0F, second & 0x7F
            if size == 126:
                size = struct.unpack(">H", self._exact(2))[0]
            elif size == 127:
                size = struct.unpack(">Q", self._exact(8))[0]
            payload = self._exact(size)
            if opcode == 0x9:
                self._send(0xA, payload)
                continue
            if opcode == 0x8:
                raise BrowserError("DevTools closed the WebSocket")
            message += payload
            if first & 0x80:
                return message.decode()

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()


class Chromium:
    """A headless Chromium with one page, driven over the DevTools protocol.

    Args:
        executable: the browser (default :func:`find_chromium`).
        width, height: the window, px.
        timeout_s: the longest any one answer may take (a guard, not a measurement).
    """

    def __init__(
        self,
        executable: str | None = None,
        width: int = 1400,
        height: int = 1050,
        timeout_s: float = 120.0,
    ):
        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError("no chromium found (apt-get install chromium)")
        self._profile = tempfile.mkdtemp(prefix="forcelearn-chromium-")
        self._process = subprocess.Popen(
            [
                exe,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--no-default-browser-check",
                "--hide-scrollbars",
                "--remote-debugging-address=127.0.0.1",
                "--remote-debugging-port=0",
                f"--user-data-dir={self._profile}",
                f"--window-size={width},{height}",
                "about:blank",
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        self._next_id = 0
        self._ws: _WebSocket | None = None
        try:
            endpoint = self._devtools_endpoint(timeout_s)
            self._ws = _WebSocket(self._page_target(endpoint), timeout_s)
        except BaseException:
            self.close()
            raise

    def _devtools_endpoint(self, timeout_s: float) -> str:
        lines: queue.Queue[str | None] = queue.Queue()
        assert self._process.stderr is not None
        stderr = self._process.stderr

        def pump() -> None:
            for line in stderr:
                lines.put(line)
            lines.put(None)

        threading.Thread(target=pump, daemon=True).start()
        while True:
            try:
                line = lines.get(timeout=timeout_s)
            except queue.Empty as exc:
                raise BrowserError("chromium did not open its DevTools port") from exc
            if line is None:
                raise BrowserError("chromium exited before opening its DevTools port")
            if "DevTools listening on " in line:
                return line.split("DevTools listening on ", 1)[1].strip()

    @staticmethod
    def _page_target(browser_ws: str) -> str:
        host = urlsplit(browser_ws).netloc
        with urllib.request.urlopen(f"http://{host}/json/list", timeout=30) as answer:
            targets = json.load(answer)
        pages = [t for t in targets if t.get("type") == "page"]
        if not pages:
            raise BrowserError("chromium has no page target")
        return str(pages[0]["webSocketDebuggerUrl"])

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """One DevTools command; its result."""
        ws = self._ws
        if ws is None:
            raise BrowserError(f"{method}: the browser is closed")
        self._next_id += 1
        ident = self._next_id
        ws.send_text(json.dumps({"id": ident, "method": method, "params": params}))
        while True:
            message = json.loads(ws.recv_text())
            if message.get("id") == ident:
                if "error" in message:
                    raise BrowserError(f"{method}: {message['error']}")
                return dict(message.get("result", {}))

    def navigate(self, url: str) -> None:
        """Open ``url`` in the page."""
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str) -> Any:
        """Evaluate JavaScript (awaiting a promise); its value."""
        result = self.call(
            "Runtime.evaluate", expression=expression, awaitPromise=True, returnByValue=True
        )
        if "exceptionDetails" in result:
            raise BrowserError(f"page script failed: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_rendered(self, canvases: int, after_trial: int = -1) -> dict[str, Any]:
        """Wait for ``canvases`` drawn plots and a status trial above ``after_trial``.

        Synchronised on the page's own ``live-rendered`` event; returns the
        page's status texts and its trial index.
        """
        script = f"""
        new Promise((resolve) => {{
          const trial = () => document.body.dataset.trial;
          const ready = () => document.querySelectorAll('canvas[data-drawn]').length >= {canvases}
            && trial() !== '' && Number(trial()) > {after_trial};
          const answer = () => resolve({{
            trial: Number(document.body.dataset.trial),
            trials_done: Number(document.body.dataset.trialsDone),
            status: document.getElementById('s-trial').textContent,
            state: document.getElementById('s-state').textContent,
            drawn: document.querySelectorAll('canvas[data-drawn]').length,
          }});
          if (ready()) return answer();
          document.addEventListener('live-rendered', function check() {{
            if (ready()) {{ document.removeEventListener('live-rendered', check); answer(); }}
          }});
        }})"""
        return dict(self.evaluate(script))

    def screenshot(self, path: Path) -> Path:
        """Save the page as a PNG."""
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self) -> None:
        """End the browser and remove its profile; safe to call twice."""
        ws = self._ws
        if ws is not None:
            ws.close()
            self._ws = None
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> Chromium:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def main(argv: list[str] | None = None) -> int:
    """Screenshot a live page once its plots are drawn and its trial has advanced."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("url")
    parser.add_argument("out", type=Path)
    parser.add_argument("--canvases", type=int, default=4, help="plots to wait for (contour: 2)")
    parser.add_argument("--after-trial", type=int, default=-1, help="wait for a trial above this")
    parser.add_argument("--timeout-s", type=float, default=900.0, help="longest wait, s")
    args = parser.parse_args(argv)
    with Chromium(timeout_s=args.timeout_s) as browser:
        browser.navigate(args.url)
        seen = browser.wait_rendered(args.canvases, args.after_trial)
        browser.screenshot(args.out)
    print(json.dumps(seen))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
