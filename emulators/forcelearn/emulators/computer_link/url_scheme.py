"""The ``forcelearn-robot://`` pyserial URL scheme: its name and its registration.

pyserial has no plugin registry: it looks a scheme up as the module
``protocol_<scheme>`` of each package in ``serial.protocol_handler_packages``.
:func:`register_url_handler` adds :mod:`forcelearn.emulators.urlhandler` there.
"""

from __future__ import annotations

SCHEME = "forcelearn-robot"
REGISTRY_KIND = "robot"
"""Kind under which in-process controllers register (``forcelearn-robot://NAME``)."""
HANDLER_PACKAGE = "forcelearn.emulators.urlhandler"


def register_url_handler() -> None:
    """Make ``serial.serial_for_url`` find ``forcelearn-robot://`` (idempotent)."""
    import serial

    if HANDLER_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(HANDLER_PACKAGE)
