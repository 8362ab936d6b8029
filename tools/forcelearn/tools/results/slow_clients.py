"""Does a crowd of slow clients on the live page slow the run? A measurement, not a test.

``python -m forcelearn.tools.results.slow_clients --trials 50 --repeats 3 --clients 150`` runs
the default job as ``forcelearn run --live`` subprocesses, interleaved: with nobody on
the page, and with ``--clients`` slow clients kept on it for the whole run (silent,
dripping a byte every 50 ms, half a request, or pipelining requests they never read;
each reconnects as soon as the server closes it). It prints each run's wall time of
the trials (``summary.json`` ``wall_s``), the median slowdown, and how many
connections the server closed (idle timeout) or refused (503, over the cap).
"""

from __future__ import annotations

import argparse
import json
import re
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
from pathlib import Path

_URL = re.compile(r"live page: (http://\S+)")
KINDS = ("silent", "drip", "half", "unread")
REQUEST = b"GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + b"a" * 4000


class SlowCrowd:
    """``count`` slow clients on ``url`` until :meth:`stop`; each reconnects when closed."""

    def __init__(self, url: str, count: int) -> None:
        split = urllib.parse.urlsplit(url)
        assert split.hostname is not None and split.port is not None
        self.address = (split.hostname, split.port)
        self.count = count
        self.closed_by_server = 0
        self.refused = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="slow-crowd", daemon=True)
        self._thread.start()

    def _open(self, behaviour: str) -> socket.socket | None:
        try:
            sock = socket.create_connection(self.address, timeout=2)
        except OSError:
            return None
        sock.setblocking(False)
        try:
            if behaviour == "half":
                sock.send(REQUEST[:30])
            elif behaviour == "unread":
                sock.send(b"GET /static/live.js HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n" * 50)
        except OSError:
            pass
        return sock

    def _run(self) -> None:
        clients: list[tuple[str, socket.socket, int]] = []
        while not self._stop.is_set():
            while len(clients) < self.count and not self._stop.is_set():
                behaviour = KINDS[len(clients) % len(KINDS)]
                sock = self._open(behaviour)
                if sock is None:
                    break
                clients.append((behaviour, sock, 0))
            kept = []
            for behaviour, sock, sent in clients:
                alive = True
                try:
                    if behaviour == "drip" and sent < len(REQUEST):
                        sock.send(REQUEST[sent : sent + 1])
                        sent += 1
                    if behaviour != "unread":
                        data = sock.recv(65536)
                        if not data:
                            alive = False
                        elif b" 503 " in data[:20]:
                            self.refused += 1
                except BlockingIOError:
                    pass
                except OSError:
                    alive = False
                if alive:
                    kept.append((behaviour, sock, sent))
                else:
                    self.closed_by_server += 1
                    sock.close()
            clients = kept
            self._stop.wait(0.05)
        for _, sock, _ in clients:
            sock.close()

    def stop(self) -> None:
        """Close every client and end."""
        self._stop.set()
        self._thread.join(timeout=10)


def one_run(trials: int, seed: int, clients: int, folder: Path) -> tuple[float, SlowCrowd | None]:
    """One ``forcelearn run --live``; its trials' wall time, s, and the crowd (if any)."""
    out = folder / f"run-{time.monotonic_ns()}"
    command = [sys.executable, "-m", "forcelearn.tools.cli", "run", "--no-progress",
               "--trials", str(trials), "--seed", str(seed), "--out", str(out),
               "--live", "--live-port", "0"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
    assert process.stderr is not None
    crowd = None
    for line in process.stderr:
        match = _URL.search(line)
        if match:
            if clients:
                crowd = SlowCrowd(match.group(1), clients)
            break
    threading.Thread(target=lambda: list(process.stderr or []), daemon=True).start()
    process.wait()
    if crowd is not None:
        crowd.stop()
    if process.returncode not in (0, 3):
        raise SystemExit(f"forcelearn run ended with exit {process.returncode}")
    wall: float = json.loads((out / "summary.json").read_text())["wall_s"]
    return wall, crowd


def main(argv: list[str] | None = None) -> int:
    """Command line (see the module's docstring)."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.results.slow_clients",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--clients", type=int, default=150)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    walls: dict[str, list[float]] = {"alone": [], "crowd": []}
    with tempfile.TemporaryDirectory(prefix="forcelearn-slow-") as tmp:
        for repeat in range(args.repeats):
            for setting in ("alone", "crowd"):
                wall, crowd = one_run(args.trials, args.seed, args.clients if setting == "crowd"
                                      else 0, Path(tmp))
                walls[setting].append(wall)
                extra = (f"  server closed {crowd.closed_by_server} slow connections, "
                         f"{crowd.refused} answered 503" if crowd else "")
                print(f"repeat {repeat}  {setting:6s} {wall:7.2f} s{extra}", flush=True)
    alone, crowd_wall = statistics.median(walls["alone"]), statistics.median(walls["crowd"])
    print(f"median: alone {alone:.2f} s, with {args.clients} slow clients {crowd_wall:.2f} s "
          f"({100 * (crowd_wall / alone - 1):+.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
