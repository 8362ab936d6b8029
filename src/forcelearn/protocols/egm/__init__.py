"""ABB EGM: ``proto`` (ABB's egm.proto for RobotWare 6 and 7, generated modules) and ``codec``."""
