"""Pure physics shared by the emulators: cell pose, contact environments, tool load."""
