"""The fabric accelerometer: a device like the others (serial, CSV replay, simulated)."""

from __future__ import annotations

from fydpad.accel.base import Accelerometer, AccelError


def open_accelerometer(spec: str, plant: object | None = None,
                       timeout_s: float = 0.5) -> Accelerometer:
    """``sim`` (needs the simulated ``plant``), ``replay:FILE.csv`` or ``serial:PORT[@BAUD]``
    (docs/accel_protocol.md; 921600 baud by default; silent for ``timeout_s`` is a fault).
    AccelError says what to fix."""
    kind, _, arg = spec.partition(":")
    if kind == "sim":
        # lazy, as each backend: fydpad.config imports this package (for accel.config)
        from fydpad.accel.sim import SimAccelerometer
        from fydpad.motors.sim import FabricMotorPlant
        if not isinstance(plant, FabricMotorPlant):
            raise AccelError("accelerometer 'sim' needs the simulated motors (--motors sim)")
        return SimAccelerometer(plant)
    if kind == "replay" and arg:
        # lazy: vision.recording loads OpenCV
        from fydpad.accel.replay import ReplayAccelerometer
        return ReplayAccelerometer(arg)
    if kind == "serial":
        # lazy, as each backend: fydpad.config imports this package (for accel.config)
        from fydpad.accel.serial import DEFAULT_BAUD, SerialAccelerometer
        from vision.serial_line import parse_serial_spec
        try:
            port, baud = parse_serial_spec(spec, DEFAULT_BAUD, what="accelerometer")
        except ValueError as exc:
            raise AccelError(str(exc)) from None
        return SerialAccelerometer(port, baud, timeout_s=timeout_s)
    raise AccelError(f"accelerometer spec {spec!r}: expected sim, replay:FILE.csv "
                     "or serial:PORT[@BAUD]")
