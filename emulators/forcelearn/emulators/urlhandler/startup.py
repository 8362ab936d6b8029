"""Run by the wheel's ``forcelearn-serial-url.pth`` at interpreter start: register ``forcelearn-robot://``.

A ``.pth`` hook must never stop the interpreter, so any failure is swallowed
(the scheme then works once an in-process emulator starts).
"""

try:
    from forcelearn.emulators.computer_link.url_scheme import register_url_handler

    register_url_handler()
except Exception:  # see the module docstring
    pass
