"""All-pole fits to a log power spectrum (autocorrelation by inverse FFT)."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sl
from numpy.typing import NDArray

from fydpad.texture.lpc import is_stable, levinson

Array = NDArray[np.float64]
NFFT = 8192


def ar_from_log_psd(log_p: Array, order: int) -> tuple[Array, float]:
    """All-pole fit (A, sigma^2) of order ``order`` to a log spectrum from :func:`log_psd`."""
    n = 2 * (log_p.size - 1)
    r = np.fft.irfft(np.exp(log_p), n)[: order + 1]
    r[0] *= 1.0 + 1e-9  # the white floor of lpc_autocorrelation: well conditioned at order 200
    a = np.concatenate([[1.0], sl.solve_toeplitz(r[:order], -r[1:order + 1])])
    if not is_stable(a):  # rounding at extreme dynamic range: the recursion keeps |k| < 1
        a, err, _ = levinson(r, order)
        return a, err
    return a, float(r[0] + np.dot(a[1:], r[1:order + 1]))
