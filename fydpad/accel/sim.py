"""A simulated fabric accelerometer reading :class:`fydpad.motors.sim.FabricMotorPlant`.

Axis convention: x is the fabric's stretch direction (roller 0 -> roller 1), the plant's
``fabric_accel_m_s2``; y is across the fabric (0 + noise); z is normal to the fabric and
carries gravity (+9.81 m/s^2 for a part lying flat, face up). Modelled part: an
ADXL345-class MEMS at +-16 g full resolution, 13 bit, 3.9 mg/LSB (0.0383 m/s^2), with
white noise (default 0.0 m/s^2 rms; a real part is ~0.03 m/s^2 rms at 1 kHz bandwidth).
Samples are the plant's 1 kHz ticks (its accel log).
"""

from __future__ import annotations

from types import TracebackType

import numpy as np
from numpy.typing import NDArray

from fydpad.accel.base import AccelError
from fydpad.motors.sim import FabricMotorPlant

G_M_S2 = 9.80665
#: ADXL345 full-resolution step: 3.9 mg/LSB.
LSB_M_S2 = 0.0039 * G_M_S2
FULL_SCALE_M_S2 = 16.0 * G_M_S2


class SimAccelerometer:
    """An :class:`~fydpad.accel.base.Accelerometer` on the simulated plant."""

    def __init__(self, plant: FabricMotorPlant, noise_m_s2: float = 0.0,
                 gravity_z_m_s2: float = G_M_S2, lsb_m_s2: float = LSB_M_S2,
                 capacity: int = 600_000, seed: int = 0) -> None:
        self.plant = plant
        self.rate_hz = 1.0 / plant.config.dt_s
        self.noise_m_s2 = float(noise_m_s2)
        self.gravity_z_m_s2 = float(gravity_z_m_s2)
        self.lsb_m_s2 = float(lsb_m_s2)
        self.capacity = int(capacity)  # ticks logged; 600 000 = 10 min at 1 kHz
        self._rng = np.random.default_rng(seed)
        self._seen = 0
        self._connected = False

    def connect(self) -> None:
        self.plant.enable_accel_log(self.capacity)
        self._seen = 0
        self._connected = True

    def read(self, timeout_s: float = 0.1) -> NDArray[np.float64]:
        if not self._connected:
            raise AccelError("sim accelerometer: read before connect()")
        log = self.plant.accel_log()
        if len(log) >= self.capacity and self._seen >= self.capacity:
            raise AccelError(f"sim accelerometer: log full after {self.capacity} ticks; "
                             "raise `capacity` or reconnect")
        new = log[self._seen:]
        self._seen = len(log)
        n = len(new)
        out = np.empty((n, 4))
        out[:, 0] = new[:, 0]
        out[:, 1] = new[:, 1]
        out[:, 2] = 0.0
        out[:, 3] = self.gravity_z_m_s2
        if self.noise_m_s2 > 0.0:
            out[:, 1:] += self._rng.normal(0.0, self.noise_m_s2, (n, 3))
        # the MEMS part's quantisation and range
        q = np.round(out[:, 1:] / self.lsb_m_s2) * self.lsb_m_s2
        out[:, 1:] = np.clip(q, -FULL_SCALE_M_S2, FULL_SCALE_M_S2)
        return out

    def disconnect(self) -> None:
        self._connected = False

    def __enter__(self) -> SimAccelerometer:
        self.connect()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.disconnect()
