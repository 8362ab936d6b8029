"""pyserial looks up ``forcelearn-robot://`` here (module named after the scheme)."""

from forcelearn.emulators.robot_controller.serial_port import EmulatedRobotSerial as Serial

__all__ = ["Serial"]
