"""pyserial looks up ``forcelearn-robot://`` here (module named after the scheme)."""

from forcelearn.emulators.computer_link.serial_port import EmulatedRobotSerial as Serial

__all__ = ["Serial"]
