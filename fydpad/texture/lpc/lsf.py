"""Line spectral frequencies (LSF) of an LPC polynomial and back.

P(z) = A(z) + z^-(p+1) A(1/z) and Q(z) = A(z) - z^-(p+1) A(1/z) have all their zeros
on the unit circle; A is minimum phase exactly when those zeros interlace. Sorted LSFs
in (0, pi) therefore stay a stable filter under any convex combination, which is why
the renderer interpolates here rather than on the coefficients (the paper's way).

LSFs are found on a dense FFT grid (robust at order 200, where np.roots loses the
clustered zeros), then refined by a few secant steps.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def _sym_parts(a: Array) -> tuple[Array, Array]:
    ext = np.concatenate([a, [0.0]])
    rev = ext[::-1]
    return ext + rev, ext - rev


def _remove_trivial(p_poly: Array, q_poly: Array, order: int) -> tuple[Array, Array]:
    """Divide out the fixed zeros: z=-1 from P and z=+1 from Q (even order), or both from Q."""
    if order % 2 == 0:
        p_red = np.polydiv(p_poly, [1.0, 1.0])[0]
        q_red = np.polydiv(q_poly, [1.0, -1.0])[0]
    else:
        p_red = p_poly
        q_red = np.polydiv(q_poly, [1.0, 0.0, -1.0])[0]
    return p_red, q_red


def _real_response(sym: Array, w: Array) -> Array:
    """R(w) with sym(e^jw) = e^{-jwm} R(w), sym palindromic of degree 2m: a cosine series."""
    deg = sym.size - 1
    m = deg / 2.0
    n = np.arange(sym.size)
    return np.cos(np.outer(w, n - m)) @ sym


def _zeros_on_grid(sym: Array, count: int, grid: int) -> Array:
    if count == 0:
        return np.zeros(0)
    deg = sym.size - 1
    m = deg / 2.0
    while True:
        nfft = grid
        spec = np.fft.rfft(sym, nfft)
        w = 2 * np.pi * np.arange(spec.size) / nfft
        vals = (spec * np.exp(1j * w * m)).real
        s = np.sign(vals)
        idx = np.flatnonzero(s[:-1] * s[1:] < 0)
        exact = np.flatnonzero(vals[1:-1] == 0) + 1
        if idx.size + exact.size == count or grid >= 1 << 22:
            break
        grid *= 4
    lo, hi = w[idx], w[idx + 1]
    flo, fhi = vals[idx], vals[idx + 1]
    for _ in range(30):  # regula falsi / bisection hybrid, vectorised over all zeros
        mid = lo - flo * (hi - lo) / (fhi - flo)
        bad = ~((mid > lo) & (mid < hi))
        mid[bad] = 0.5 * (lo[bad] + hi[bad])
        fm = _real_response(sym, mid)
        left = np.sign(fm) == np.sign(flo)
        lo = np.where(left, mid, lo)
        flo = np.where(left, fm, flo)
        hi = np.where(left, hi, mid)
        fhi = np.where(left, fhi, fm)
        # Illinois tweak keeps regula falsi from stalling on one side
        flo = np.where(left, flo, flo * 0.5)
        fhi = np.where(left, fhi * 0.5, fhi)
        if lo.size == 0 or np.max(hi - lo) < 1e-13:
            break
    z = np.sort(np.concatenate([0.5 * (lo + hi), w[exact]]))
    return z


def poly_to_lsf(a: ArrayLike, grid: int = 1 << 14) -> Array:
    """Sorted LSFs in radians (0, pi) of a stable polynomial A (length p+1)."""
    a = np.asarray(a, float)
    a = a / a[0]
    order = a.size - 1
    p_poly, q_poly = _sym_parts(a)
    p_red, q_red = _remove_trivial(p_poly, q_poly, order)
    np_ = (p_red.size - 1) // 2
    nq = (q_red.size - 1) // 2
    zp = _zeros_on_grid(p_red, np_, grid)
    zq = _zeros_on_grid(q_red, nq, grid)
    if zp.size != np_ or zq.size != nq:
        raise ValueError("polynomial is not minimum phase: its LSFs do not interlace")
    lsf = np.sort(np.concatenate([zp, zq]))
    return lsf


def lsf_to_poly(lsf: ArrayLike) -> Array:
    """Polynomial A (leading 1) from sorted LSFs; evaluated as a product on an FFT grid.

    The product of the quadratic factors is formed pointwise in frequency and brought
    back by one inverse FFT, which keeps full precision at order 200 (a chain of
    convolutions would pass through huge intermediate coefficients).
    """
    lsf = np.sort(np.asarray(lsf, float))
    order = lsf.size
    # Interlacing: the zeros of P are the odd-indexed ones (1st, 3rd, ...) for A stable.
    wp = lsf[0::2]
    wq = lsf[1::2]
    n = 1 << int(np.ceil(np.log2(order + 2)) + 1)
    z1 = np.exp(-2j * np.pi * np.arange(n) / n)  # z^-1 on the grid
    pf = np.ones(n, complex)
    qf = np.ones(n, complex)
    for w in wp:
        pf *= 1.0 - 2.0 * np.cos(w) * z1 + z1 * z1
    for w in wq:
        qf *= 1.0 - 2.0 * np.cos(w) * z1 + z1 * z1
    if order % 2 == 0:
        pf *= 1.0 + z1
        qf *= 1.0 - z1
    else:
        qf *= 1.0 - z1 * z1
    p_poly = np.fft.ifft(pf).real[: order + 2]
    q_poly = np.fft.ifft(qf).real[: order + 2]
    a = 0.5 * (p_poly + q_poly)[: order + 1]
    a[0] = 1.0
    return a
