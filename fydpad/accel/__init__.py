"""The fabric accelerometer: a device like the others (serial, CSV replay, simulated)."""

from __future__ import annotations

from fydpad.accel.base import Accelerometer, AccelError


def open_accelerometer(spec: str, plant: object | None = None) -> Accelerometer:
    """``sim`` (needs the simulated ``plant``), ``replay:FILE.csv``; ``serial:PORT[@BAUD]``
    is not implemented yet. AccelError says what to fix."""
    kind, _, arg = spec.partition(":")
    if kind == "sim":
        from fydpad.accel.sim import SimAccelerometer
        from fydpad.motors.sim import FabricMotorPlant
        if not isinstance(plant, FabricMotorPlant):
            raise AccelError("accelerometer 'sim' needs the simulated motors (--motors sim)")
        return SimAccelerometer(plant)
    if kind == "replay" and arg:
        from fydpad.accel.replay import ReplayAccelerometer
        return ReplayAccelerometer(arg)
    if kind == "serial":
        raise AccelError(f"accelerometer {spec!r}: the serial backend is not implemented yet "
                         "(issue 8); use replay:FILE.csv or sim")
    raise AccelError(f"accelerometer spec {spec!r}: expected sim, replay:FILE.csv "
                     "or serial:PORT[@BAUD]")
