"""Software emulators of the cell's devices; they speak the devices' wire protocols."""
