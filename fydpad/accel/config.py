"""The ``[accel]`` section of the station's TOML config."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class AccelConfig:
    """The fabric accelerometer: which device, and the simulated part's noise."""

    #: ``sim``, ``replay:FILE.csv`` or ``serial:PORT[@BAUD]`` (see fydpad.accel).
    device: str = "sim"
    #: White noise of the simulated part, m/s^2 rms (an ADXL345 is ~0.03 at 1 kHz).
    sim_noise_m_s2: float = 0.0
    #: A serial accelerometer that sends no valid sample for this long is a fault, s.
    serial_timeout_s: float = 0.5
