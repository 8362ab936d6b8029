"""Device drivers: two robots (computer link, EGM) and two force/torque sensors (JR3, Net F/T).

The ABB robot over its computer link (pyserial) or EGM (UDP), the JR3 sensor
over CAN (python-can), the ATI Net F/T over Ethernet. All four share one
lifecycle (:mod:`forcelearn.drivers.lifecycle`, docs/drivers.md): entering
``with`` opens the device, robots included; closing stops it.
"""
