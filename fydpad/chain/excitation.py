"""The excitation of the chain identification (Felicetti 2022 section 3.2: a random signal
between 10 and 1000 Hz; here capped below the output channel's Nyquist)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fydpad.chain import ChainError

#: The band is kept below this fraction of the Nyquist rate: the ZOH and the Welch
#: window roll off at Nyquist, and a channel's own anti-image filter starts before it.
NYQUIST_FRACTION = 0.9


def check_band(band_hz: tuple[float, float], rate_hz: float) -> tuple[float, float]:
    """``band_hz`` if it is a usable band for a channel at ``rate_hz``, else ChainError."""
    lo, hi = float(band_hz[0]), float(band_hz[1])
    top = NYQUIST_FRACTION * 0.5 * rate_hz
    if not (0.0 < lo < hi):
        raise ChainError(f"band {lo:g}-{hi:g} Hz: expected 0 < LO < HI")
    if hi > top:
        raise ChainError(f"band {lo:g}-{hi:g} Hz: HI must stay below {top:g} Hz "
                         f"({NYQUIST_FRACTION:g} of the {rate_hz:g} Hz channel's Nyquist)")
    return lo, hi


def band_noise(n: int, rate_hz: float, band_hz: tuple[float, float], peak: float,
               seed: int = 0) -> NDArray[np.float64]:
    """``n`` samples of seeded random noise, flat over ``band_hz`` and zero outside,
    scaled so that its largest sample is ``peak`` (the drive's vibration headroom sets
    it: a scaled peak cannot clip eq. 3)."""
    lo, hi = check_band(band_hz, rate_hz)
    rng = np.random.default_rng(seed)
    spec = rng.normal(size=n // 2 + 1) + 1j * rng.normal(size=n // 2 + 1)
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    spec[(f < lo) | (f > hi)] = 0.0
    x = np.fft.irfft(spec, n)
    # Fade in and out over 50 ms: no step at the start or the end of the drive.
    ramp = min(int(0.05 * rate_hz), n // 4)
    if ramp > 0:
        w = 0.5 - 0.5 * np.cos(np.pi * np.arange(ramp) / ramp)
        x[:ramp] *= w
        x[n - ramp:] *= w[::-1]
    return x * (peak / np.max(np.abs(x)))
