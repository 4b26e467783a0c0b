"""DFT321 (paper III-B, [23]) and the 10 Hz high-pass of tool motion (paper IV-A).

DFT321 maps three acceleration axes to one signal whose energy spectrum is the sum of
the three axes' energy spectra: magnitude ``sqrt(|X|^2+|Y|^2+|Z|^2)``, phase of
``X+Y+Z``. It is done over overlapping windows (STFT) so recordings of any length work
and the phase follows the signal's local structure.
"""

from __future__ import annotations

import numpy as np
import scipy.signal as ss
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def highpass(x: ArrayLike, fs: float, cutoff_hz: float = 10.0, order: int = 4) -> Array:
    """Zero-phase Butterworth high-pass along axis 0: removes hand motion and gravity."""
    x = np.asarray(x, float)
    if cutoff_hz <= 0:
        return x - x.mean(axis=0)
    sos = ss.butter(order, cutoff_hz, "highpass", fs=fs, output="sos")
    padlen = min(x.shape[0] - 1, 3 * 2 * sos.shape[0])
    return ss.sosfiltfilt(sos, x, axis=0, padlen=padlen)


def dft321(acc: ArrayLike, nperseg: int = 256) -> Array:
    """One signal from an (n, 3) acceleration array with the three axes' summed energy.

    Hann windows at 50 % overlap (a constant-overlap-add pair), so the inverse STFT
    gives back a signal of the same length whose short-time energy spectrum is the
    sum of the axes' (the DFT321 criterion), window by window.
    """
    acc = np.asarray(acc, float)
    if acc.ndim != 2 or acc.shape[1] != 3:
        raise ValueError(f"dft321 needs an (n, 3) array, got shape {acc.shape}")
    n = acc.shape[0]
    nperseg = int(min(nperseg, max(16, n)))
    if nperseg % 2:
        nperseg -= 1
    _, _, z = ss.stft(acc.T, nperseg=nperseg, noverlap=nperseg // 2, window="hann",
                      boundary="zeros", padded=True)
    mag = np.sqrt(np.sum(np.abs(z) ** 2, axis=0))
    phase = np.angle(np.sum(z, axis=0))
    _, y = ss.istft(mag * np.exp(1j * phase), nperseg=nperseg, noverlap=nperseg // 2,
                    window="hann", boundary=True)
    return np.asarray(y[:n], float)


def preprocess(acc: ArrayLike, fs: float, highpass_hz: float = 10.0) -> Array:
    """The modelling signal: each axis high-passed, then DFT321 (paper Fig. 8)."""
    return dft321(highpass(acc, fs, highpass_hz))
