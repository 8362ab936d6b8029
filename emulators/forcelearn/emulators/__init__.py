"""Software emulators of the cell's devices; they speak the devices' wire protocols.

Two in-process routes reach them the way python-can and pyserial users reach
hardware: the ``forcelearn-jr3`` python-can interface (a ``can.interface``
entry point) and the ``forcelearn-robot://`` pyserial URL scheme
(:mod:`.computer_link.serial_port`, registered by the wheel's ``.pth`` hook
and by any in-process controller emulator when it starts).
"""
