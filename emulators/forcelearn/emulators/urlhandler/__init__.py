"""pyserial URL handlers of the emulators (``serial.protocol_handler_packages`` entry)."""
