"""Names of the in-process emulators this process runs, for the URL and bus routes.

``serial.serial_for_url("forcelearn-robot://NAME")`` and
``can.Bus(interface="forcelearn-jr3", channel="NAME")`` attach to the emulator
registered here under NAME (each kind has its own names), as python-can's
``virtual`` interface joins a channel by name. An emulator registers when it
starts serving and unregisters when it closes.
"""

from __future__ import annotations

import threading
import uuid
from typing import Any

_lock = threading.Lock()
_devices: dict[tuple[str, str], Any] = {}


def new_name(prefix: str) -> str:
    """A name no other emulator of this process uses (``prefix-<8 hex>``)."""
    return f"{prefix}-{uuid.uuid4().hex[:8]}"


def register(kind: str, name: str, device: Any) -> None:
    """Make ``device`` reachable as ``name``; a name in use raises ValueError."""
    if not name or "/" in name or "?" in name:
        raise ValueError(f"emulator name {name!r}: a non-empty name without '/' or '?'")
    with _lock:
        if (kind, name) in _devices and _devices[(kind, name)] is not device:
            raise ValueError(f"an in-process {kind} emulator named {name!r} is already running")
        _devices[(kind, name)] = device


def unregister(kind: str, name: str, device: Any) -> None:
    """Forget ``name`` if it still names ``device``."""
    with _lock:
        if _devices.get((kind, name)) is device:
            del _devices[(kind, name)]


def lookup(kind: str, name: str) -> Any | None:
    """The emulator registered as ``name``, or None."""
    with _lock:
        return _devices.get((kind, name))


def names(kind: str) -> list[str]:
    """Names of the running in-process emulators of ``kind`` (for error messages)."""
    with _lock:
        return sorted(n for k, n in _devices if k == kind)
