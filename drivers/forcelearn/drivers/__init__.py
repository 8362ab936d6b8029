"""Device drivers: the ABB computer link (pyserial) and the JR3 sensor over CAN (python-can)."""
