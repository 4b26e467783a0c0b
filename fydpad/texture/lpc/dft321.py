"""The modelling signal of a scan: the 10 Hz high-pass of tool motion (Bianchi 2015
IV-A) and DFT321 (III-B; Landin et al. 2010)."""

from __future__ import annotations

import numpy as np
import scipy.signal as ss
from numpy.typing import ArrayLike, NDArray


def preprocess(acc: ArrayLike, fs: float, highpass_hz: float = 10.0) -> NDArray[np.float64]:
    """Each axis of an (n, 3) acceleration high-passed (4th-order Butterworth, zero phase:
    the hand's motion and gravity; the mean removed at 0 Hz), then DFT321: one signal of
    magnitude sqrt(|X|^2 + |Y|^2 + |Z|^2) and the phase of X + Y + Z, over Hann windows at
    50 % overlap (a constant-overlap-add pair: the inverse STFT gives a signal of the same
    length whose short-time energy spectrum is the sum of the axes')."""
    x = np.asarray(acc, float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"dft321 needs an (n, 3) array, got shape {x.shape}")
    if highpass_hz <= 0:
        x = x - x.mean(axis=0)
    else:
        sos = ss.butter(4, highpass_hz, "highpass", fs=fs, output="sos")
        x = ss.sosfiltfilt(sos, x, axis=0, padlen=min(x.shape[0] - 1, 6 * sos.shape[0]))
    n = x.shape[0]
    nperseg = int(min(256, max(16, n)))
    nperseg -= nperseg % 2
    _, _, z = ss.stft(x.T, nperseg=nperseg, noverlap=nperseg // 2, window="hann",
                      boundary="zeros", padded=True)
    mag = np.sqrt(np.sum(np.abs(z) ** 2, axis=0))
    _, y = ss.istft(mag * np.exp(1j * np.angle(np.sum(z, axis=0))), nperseg=nperseg,
                    noverlap=nperseg // 2, window="hann", boundary=True)
    return np.asarray(y[:n], float)
