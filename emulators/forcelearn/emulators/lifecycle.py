"""The one lifecycle every emulator shares: construct, ``start()``, ``close()``; a context manager.

* ``address``: what a client opens to reach it: a pyserial URL or pty path
  (robot controller, slcan adapter), a python-can channel (JR3 node), or
  ``host:port`` (EGM controller, Net F/T box).
* ``start()`` begins serving and returns ``address``; a second call does
  nothing. Emulators that serve from construction (the JR3 node, the Net F/T
  box) are started already.
* ``close()`` stops serving, joins its threads and releases its ports; a
  second call does nothing; a closed emulator cannot start again.
* ``with`` starts it and closes it; one collected while serving warns
  (``ResourceWarning``) and is closed, as an unclosed file or python-can bus is.
"""

from __future__ import annotations

import warnings
from typing import Any


class Emulator:
    """Base of the emulators' lifecycle; subclasses define ``_start_serving``, ``_release``."""

    _started = False
    _closed = False

    @property
    def address(self) -> str:
        """What a client opens to reach this emulator."""
        raise NotImplementedError

    @property
    def closed(self) -> bool:
        """True once :meth:`close` has run."""
        return self._closed

    def start(self) -> str:
        """Begin serving (idempotent); return :attr:`address`."""
        if self._closed:
            raise RuntimeError(f"this {type(self).__name__} was closed; create a new one")
        if not self._started:
            self._start_serving()
            self._started = True
        return self.address

    def close(self) -> None:
        """Stop serving, join threads, release ports (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._release()

    def _start_serving(self) -> None:
        """Start serving (threads, registration)."""

    def _release(self) -> None:
        """Stop serving and release everything."""

    def _mark_started(self) -> None:
        """For emulators that serve from construction."""
        self._started = True

    def __enter__(self) -> Any:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __del__(self) -> None:
        if self._started and not self._closed:
            # At interpreter exit the warnings and contextlib modules may already be gone
            # (module globals set to None): a plain try keeps shutdown quiet.
            try:  # noqa: SIM105 (contextlib may be gone at exit)
                warnings.warn(
                    f"{type(self).__name__} was not closed: call close() or use it in a with "
                    "block",
                    ResourceWarning,
                    stacklevel=2,
                )
            except Exception:
                pass
            try:  # noqa: SIM105
                self.close()
            except Exception:
                pass
