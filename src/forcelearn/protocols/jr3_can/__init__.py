"""JR3-to-CAN adapter protocol: ``opcodes`` (versioned table), ``codec`` (frames), ``scaling``."""
