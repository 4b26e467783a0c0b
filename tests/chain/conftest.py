"""The simulated chain the tests identify: the fabric and motor plant through the motor
drive at 1 kHz, its accelerometer (ADXL345-class noise), the simulated finger at 0.3 N."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fydpad.chain.session import open_session
from fydpad.config import StationConfig

#: An ADXL345 at 1 kHz bandwidth: ~0.03 m/s^2 rms noise (on top of its 3.9 mg LSB).
NOISE_M_S2 = 0.03
BAND_HZ = (10.0, 450.0)


def sim_config(noise_m_s2: float = NOISE_M_S2) -> StationConfig:
    cfg = StationConfig()
    return replace(cfg, accel=replace(cfg.accel, sim_noise_m_s2=noise_m_s2))


@pytest.fixture()
def session():
    s = open_session(sim_config(), "sim", "sim")
    yield s
    s.close()


@pytest.fixture(scope="session")
def chain_at():
    """One simulated chain for the identification and compensation tests: ``at(k)`` is
    (session, the entry identified at k over 30 s, seed 2), each k identified once (the
    30 s runs are most of these tests' time). Tests that use the session after another
    may have moved it: they ``hold`` their stiffness again first."""
    from fydpad.chain.identify import identify_entry

    s = open_session(sim_config(), "sim", "sim")
    cache = {}

    def at(k: float):
        if k not in cache:
            cache[k] = identify_entry(s, k, 30.0, BAND_HZ, seed=2)
        return s, cache[k]

    yield at
    s.close()


def lock_in(session, f_hz: float, amp_duty: float = 0.1, settle: int = 256,
            measure: int = 1024) -> complex:
    """Ground truth, point by point: a sine at f_hz through the same drive, ``settle`` ticks
    to settle (the fabric mode's time constant is 1/(zeta w0) ~ 7 ms at 190 Hz; against
    512 ticks, 256 changed no point by more than 0.04 dB and 0.24 degrees without sensor
    noise), then Y/X at f_hz over ``measure`` ticks, a whole number of cycles on the Welch
    bins (lock-in)."""
    from fydpad.chain.measure import drive_signal

    rate = session.rate_hz
    k = np.arange(settle + measure)
    x = amp_duty * np.sin(2 * np.pi * f_hz * k / rate)
    run = drive_signal(session.drive, session.accel, x, session.clock)
    e = np.exp(-2j * np.pi * f_hz * k[-measure:] / rate)
    return complex(run.y_m_s2[-measure:] @ e) / complex(run.x_duty[-measure:] @ e)
