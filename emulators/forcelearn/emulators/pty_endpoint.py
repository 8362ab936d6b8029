"""The device's side of a pseudo-terminal: the serial port a controller or a USB adapter presents.

Clients open :attr:`PtyEndpoint.address`, a symlink with a stable name to the
pty's slave side; the endpoint keeps its own slave descriptor open so the pty
survives clients that close it. :meth:`PtyEndpoint.hang_up` replaces the pty
(the old one reports a hang-up to its client) and repoints the symlink.

A full pty (a client that stopped reading): writes never block the emulator's
thread. What the pty cannot take is dropped whole and counted
(:attr:`PtyEndpoint.dropped_writes`), as a device's transmit buffer overflows;
the tail of a write the pty took in part goes out before anything else, so a
frame or a line is never cut.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import tempfile
import threading
import tty
from pathlib import Path

log = logging.getLogger(__name__)


class PtyEndpoint:
    """One pseudo-terminal behind a stable symlink.

    Args:
        name: used in the symlink's name (``/tmp/forcelearn-<name>-XXXX/<name>-tty``).
    """

    def __init__(self, name: str) -> None:
        self._dir = tempfile.TemporaryDirectory(prefix=f"forcelearn-{name}-")
        self._link = Path(self._dir.name) / f"{name}-tty"
        self._lock = threading.Lock()
        self._master = self._slave = -1
        self._tail = b""
        self.generation = 0
        """Changes whenever the connection is replaced (the reader drops half-read frames)."""
        self.dropped_writes = 0
        """Writes dropped because the client did not read (a full pty)."""
        self._open_pty()

    def _open_pty(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no CR -> LF translation, no echo
        os.set_blocking(self._master, False)
        temporary = self._link.with_suffix(".new")
        temporary.unlink(missing_ok=True)
        temporary.symlink_to(os.ttyname(self._slave))
        temporary.replace(self._link)

    @property
    def address(self) -> str:
        """Path of the symlink to the pty's slave side (stable across hang-ups)."""
        return str(self._link)

    def read(self, timeout_s: float) -> bytes:
        """Return what the client wrote, waiting at most ``timeout_s`` (b"" if nothing)."""
        master = self._master
        if master < 0:
            return b""
        try:
            ready, _, _ = select.select([master], [], [], timeout_s)
            if not ready:
                return b""
            return os.read(master, 4096)
        except BlockingIOError:
            return b""
        except (OSError, ValueError) as exc:  # closed meanwhile, or EIO without a slave
            if isinstance(exc, OSError) and exc.errno not in (errno.EIO, errno.EBADF):
                raise
            return b""

    def write(self, data: bytes) -> bool:
        """Queue ``data`` for the client without blocking; False (and counted) if dropped."""
        with self._lock:
            if self._master < 0:
                return False
            if self._tail:
                self._tail = self._tail[self._write_some(self._tail):]
                if self._tail:
                    self._dropped(len(data))
                    return False
            written = self._write_some(data)
            self._tail = data[written:] if written else b""
            if not written:
                self._dropped(len(data))
            return written > 0

    def _dropped(self, size: int) -> None:
        self.dropped_writes += 1
        log.warning("pty %s full: the client is not reading, %d bytes dropped", self.address, size)

    def _write_some(self, data: bytes) -> int:
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0
        except OSError as exc:  # EIO: the client side is gone
            if exc.errno != errno.EIO:
                raise
            return 0

    def hang_up(self) -> None:
        """Drop the connection: the client sees a hang-up, new clients get a new pty."""
        with self._lock:
            old = (self._master, self._slave)
            self._open_pty()  # repoint the symlink first, so a client reconnecting at once
            self._tail = b""
            for fd in old:  # after seeing the hang-up finds the new pty
                with contextlib.suppress(OSError):
                    os.close(fd)
            self.generation += 1

    def close(self) -> None:
        """Release the pty and remove the symlink; safe to call twice."""
        with self._lock:
            for fd in (self._master, self._slave):
                if fd >= 0:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self._master = self._slave = -1
        self._dir.cleanup()
