"""The wire protocols, pure: bytes and frames in, plain values out (no I/O, no threads).

Drivers and emulators both import them, so the two ends of every wire speak
one definition of it; nothing here imports a driver, an emulator, pyserial,
python-can or a socket (import-linter checks it, pyproject.toml).

* :mod:`.computer_link`: the ABB computer link's frames (``framing``) and
  messages (``messages``), docs/computer-link.md.
* :mod:`.jr3_can`: the JR3-to-CAN adapter's opcode table, frame codec and
  count scaling, docs/jr3-can.md.
* :mod:`.lawicel`: the LAWICEL (slcan) ASCII lines of a USB-CAN adapter.
* :mod:`.egm`: ABB EGM datagrams for RobotWare 6 and 7 (protobuf), docs/egm.md.
* :mod:`.netft`: ATI Net F/T RDT requests and records, calibration replies, docs/netft.md.
"""
