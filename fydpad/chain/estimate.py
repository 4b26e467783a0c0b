"""TF = CPSD_yx / PSD_x with Welch averaging, and the coherence per frequency (paper
000 eq. 1), with the checks that tell a usable measurement from a broken one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from fydpad.chain import ChainError

Array = NDArray[np.float64]

#: Coherence above which a frequency counts as identified (and scored by the check).
COHERENCE_MIN = 0.9
#: A measurement is refused when fewer than this share of the band's bins reach it.
COHERENT_SHARE_MIN = 0.5


@dataclass(frozen=True)
class TfEstimate:
    """One identified transfer function: output units per input unit at ``freqs_hz``."""

    freqs_hz: Array
    tf: NDArray[np.complex128]
    coherence: Array

    def coherent(self, band_hz: tuple[float, float],
                 threshold: float = COHERENCE_MIN) -> NDArray[np.bool_]:
        """Bins inside ``band_hz`` whose coherence exceeds ``threshold``."""
        f = self.freqs_hz
        return (f >= band_hz[0]) & (f <= band_hz[1]) & (self.coherence > threshold)


def welch_tf(x: Array, y: Array, rate_hz: float, nperseg: int = 512) -> TfEstimate:
    """H1 estimate CPSD_yx / PSD_x (Hann window, 50 % overlap) and the magnitude-squared
    coherence; scipy's ``csd(x, y)`` is E[conj(X) Y], so the ratio is Y/X."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"x and y must be 1-D of equal length, got {x.shape} {y.shape}")
    nperseg = min(nperseg, x.size)
    f, pxx = signal.welch(x, rate_hz, nperseg=nperseg)
    _, pxy = signal.csd(x, y, rate_hz, nperseg=nperseg)
    _, coh = signal.coherence(x, y, rate_hz, nperseg=nperseg)
    with np.errstate(divide="ignore", invalid="ignore"):
        tf = np.where(pxx > 0, pxy / pxx, 0.0)
    return TfEstimate(f, tf.astype(np.complex128), np.nan_to_num(coh))


def check_response(y: Array, lsb: float, full_scale: float | None, what: str) -> None:
    """Refuse a silent response (a few LSB: nothing moves the fabric, or the sensor is
    not on it) and a clipped one (samples at the sensor's full scale)."""
    rms = float(np.sqrt(np.mean((y - np.mean(y)) ** 2))) if y.size else 0.0
    if rms < lsb:
        raise ChainError(f"{what}: the response is silent ({rms:.3g} m/s^2 rms): check that "
                         "the motors are powered and the accelerometer sits on the fabric")
    if full_scale is not None:
        clipped = int(np.count_nonzero(np.abs(y) >= full_scale * (1 - 1e-9)))
        if clipped:
            raise ChainError(f"{what}: {clipped} response samples at the accelerometer's "
                             f"full scale ({full_scale:g} m/s^2): lower --level or choose "
                             "a larger range")


def check_coherence(est: TfEstimate, band_hz: tuple[float, float], what: str,
                    threshold: float = COHERENCE_MIN,
                    share_min: float = COHERENT_SHARE_MIN) -> float:
    """The share of the band's bins above ``threshold``; ChainError below ``share_min``."""
    f = est.freqs_hz
    inband = (f >= band_hz[0]) & (f <= band_hz[1])
    share = float(np.mean(est.coherence[inband] > threshold)) if inband.any() else 0.0
    if share < share_min:
        raise ChainError(
            f"{what}: too little coherence to identify: {100 * share:.0f} % of "
            f"{band_hz[0]:g}-{band_hz[1]:g} Hz above {threshold:g} (median "
            f"{np.median(est.coherence[inband]):.2f}); check that the accelerometer reads "
            "the fabric (not noise), the finger holds still, and raise --level or --seconds")
    return share
