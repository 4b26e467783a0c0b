"""The fabric accelerometer: a device like the others (serial, CSV replay, simulated)."""
