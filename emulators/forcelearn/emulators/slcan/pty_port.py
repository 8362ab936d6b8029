"""The adapter's side of a pseudo-terminal: the serial port a USB-CAN adapter would present.

Like :class:`forcelearn.emulators.robot_controller.transport.PtyEndpoint`
(a symlink with a stable name to the pty's slave side; the emulator keeps its
own slave descriptor open so the pty survives clients that close it), but
writes never block: a real adapter streaming frames to a host that stopped
reading loses them, and so does this one (``write`` returns False), instead of
stalling the bus side. Only whole writes are lost: the tail of a write the
pty took in part goes out before anything else, so a line is never cut.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import tempfile
import threading
import tty
from pathlib import Path


class PtyPort:
    """One pseudo-terminal; clients open :attr:`path`.

    Args:
        name: used in the symlink's name (``/tmp/forcelearn-<name>-XXXX/<name>-tty``).
    """

    def __init__(self, name: str = "slcan") -> None:
        self._dir = tempfile.TemporaryDirectory(prefix=f"forcelearn-{name}-")
        self._link = Path(self._dir.name) / f"{name}-tty"
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no CR -> LF translation, no echo
        os.set_blocking(self._master, False)
        self._link.symlink_to(os.ttyname(self._slave))
        self._write_lock = threading.Lock()
        self._tail = b""

    @property
    def path(self) -> str:
        """Path of the symlink to the pty's slave side."""
        return str(self._link)

    def read(self, timeout_s: float) -> bytes:
        """Return what the client wrote, waiting at most ``timeout_s`` (b"" if nothing)."""
        if self._master < 0:
            return b""
        ready, _, _ = select.select([self._master], [], [], timeout_s)
        if not ready:
            return b""
        try:
            return os.read(self._master, 4096)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno not in (errno.EIO, errno.EBADF):
                raise
            return b""

    def write(self, data: bytes) -> bool:
        """Queue ``data`` for the client without blocking; False if it was dropped."""
        with self._write_lock:
            if self._master < 0:
                return False
            if self._tail:
                self._tail = self._tail[self._write_some(self._tail) :]
                if self._tail:
                    return False
            written = self._write_some(data)
            self._tail = data[written:] if written else b""
            return written > 0

    def _write_some(self, data: bytes) -> int:
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0

    def close(self) -> None:
        """Release the pty and remove the symlink; safe to call twice."""
        with self._write_lock:
            for fd in (self._master, self._slave):
                if fd >= 0:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self._master = self._slave = -1
        self._dir.cleanup()
