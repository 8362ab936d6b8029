"""JR3 force/torque sensor over the open JR3-to-CAN adapter protocol (python-can).

Layers: :mod:`.opcodes` (versioned opcode table), :mod:`.codec` (pure frames),
:mod:`.scaling` (counts <-> N, N*m), :mod:`.pairing` (counters), :mod:`.config`,
:mod:`.listener` (bus frames -> samples) and :mod:`.driver` (the sensor).
"""
