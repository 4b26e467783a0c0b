"""Line spectral frequencies (LSF) to an LPC polynomial (the HaTT import's, Culbertson
2014). P(z), Q(z) = A(z) +- z^-(p+1) A(1/z) have their zeros on the unit circle,
interlaced exactly when A is minimum phase, so sorted LSFs in (0, pi) are a stable
filter."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def lsf_to_poly(lsf: ArrayLike) -> NDArray[np.float64]:
    """Polynomial A (leading 1) from LSFs, (p,) -> (p + 1,) or each row (k, p) -> (k, p + 1):
    P and Q as products of their quadratic factors formed pointwise on an FFT grid and
    brought back by one inverse FFT (a chain of convolutions would pass through huge
    coefficients at order 200)."""
    lsf = np.sort(np.asarray(lsf, float), axis=-1)
    order = lsf.shape[-1]
    n = 1 << int(np.ceil(np.log2(order + 2)) + 1)
    z1 = np.exp(-2j * np.pi * np.arange(n) / n)  # z^-1 on the grid
    pf = np.ones((*lsf.shape[:-1], n), complex)
    qf = np.ones_like(pf)
    for i in range(order):
        f = pf if i % 2 == 0 else qf  # interlaced: P's zeros are the 1st, 3rd, ...
        f *= 1.0 - 2.0 * np.cos(lsf[..., i:i + 1]) * z1 + z1 * z1
    if order % 2 == 0:  # the fixed zeros: z = -1 of P and z = +1 of Q, or both of Q
        pf *= 1.0 + z1
        qf *= 1.0 - z1
    else:
        qf *= 1.0 - z1 * z1
    a = 0.5 * (np.fft.ifft(pf).real + np.fft.ifft(qf).real)[..., :order + 1]
    a[..., 0] = 1.0
    return a
