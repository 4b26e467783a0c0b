"""Linear prediction (Bianchi 2015 eq. 4: autocorrelation method, Levinson-Durbin,
stability) and all-pole fits to a log spectrum. The predictor
``a(k) = e(k) + h^T [a(k-1) .. a(k-p)]`` (eq. 5) is the all-pole filter 1 / A with the
"polynomial" ``A = [1, -h_1, ..., -h_p]`` (scipy.signal's denominator)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg as sl
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
NFFT = 8192  # FFT size of the all-pole fits to a spectrum
DEFAULT_SPEEDS_MM_S = (10.0, 20.0, 30.0, 40.0)
DEFAULT_TOLERANCE_MM_S = 5.0


def levinson(r: ArrayLike, order: int) -> tuple[Array, float]:
    """Levinson-Durbin on the autocorrelation ``r`` (r[0] the signal power): A and the
    prediction-error power sigma^2 of eq. 5. A positive-definite ``r`` (any biased
    estimate) gives reflection coefficients |k_i| < 1, hence a stable 1/A."""
    r = np.asarray(r, float)
    if r.size < order + 1:
        raise ValueError(f"autocorrelation has {r.size} lags, order {order} needs {order + 1}")
    if not r[0] > 0:
        raise ValueError("signal has no power (r[0] <= 0)")
    a = np.zeros(order + 1)
    a[0] = 1.0
    err = float(r[0])
    for m in range(1, order + 1):
        km = -(r[m] + np.dot(a[1:m], r[m - 1:0:-1])) / err
        a[1:m] = a[1:m] + km * a[m - 1:0:-1]
        a[m] = km
        err *= 1.0 - km * km
        if err <= 0:  # numerically singular: the rest of the predictor adds nothing
            err = np.finfo(float).tiny
            break
    return a, float(err)


def lpc_autocorrelation(segments: Sequence[ArrayLike], order: int, floor: float = 1e-9
                        ) -> tuple[Array, float]:
    """(A, sigma^2) over several segments: their biased autocorrelations summed (no seams),
    then Levinson. A white floor (``floor`` of r[0]) keeps it well conditioned at order 200."""
    total = np.zeros(order + 1)
    n = 0
    for seg in segments:
        seg = np.asarray(seg, float)
        # n + order, not 2n - 1: a segment shorter than the order would otherwise read its
        # negative lags, wrapped round, as lags above n (no longer positive definite).
        nfft = 1 << int(np.ceil(np.log2(max(seg.size + order, 2))))
        spec = np.fft.rfft(seg, nfft)
        r = np.fft.irfft(spec.real**2 + spec.imag**2, nfft)[: order + 1]
        total[:r.size] += r  # shorter only for an empty segment
        n += seg.size
    if n <= order:
        raise ValueError(f"{n} samples cannot fit an order-{order} model")
    r = total / n
    r[0] *= 1.0 + floor
    return levinson(r, order)


def is_stable(a: ArrayLike) -> bool:
    """True when every pole of 1/A lies strictly inside the unit circle: every reflection
    coefficient of the step-down recursion |k_i| < 1."""
    a = np.asarray(a, float)
    cur = a[1:] / a[0]
    for m in range(cur.size, 0, -1):
        km = cur[m - 1]
        if not abs(km) < 1.0:  # nan too
            return False
        cur = (cur[: m - 1] - km * cur[m - 2::-1][: m - 1]) / (1.0 - km * km)
    return True


def h_from_poly(a: ArrayLike) -> Array:
    """The paper's h (eq. 4/5) from A = [1, -h]."""
    a = np.asarray(a, float)
    return -a[1:] / a[0]


def poly_from_h(h: ArrayLike) -> Array:
    """A = [1, -h] from the paper's h."""
    return np.concatenate([[1.0], -np.asarray(h, float)])


def ar_psd(a: ArrayLike, sigma2: float, freqs_hz: ArrayLike, fs_hz: float) -> Array:
    """One-sided PSD of the AR process sigma^2 / |A|^2 in units^2/Hz (eq. 5's spectrum)."""
    a = np.asarray(a, float)
    w = 2 * np.pi * np.asarray(freqs_hz, float) / fs_hz
    resp = np.exp(-1j * np.outer(w, np.arange(a.size))) @ a
    return 2.0 * sigma2 / fs_hz / np.abs(resp) ** 2


def ar_from_log_psd(log_p: Array, order: int) -> tuple[Array, float]:
    """All-pole fit (A, sigma^2) of order ``order`` to a log power spectrum on
    ``log_p.size`` frequencies 0..fs/2 (autocorrelation by inverse FFT)."""
    r = np.fft.irfft(np.exp(log_p), 2 * (log_p.size - 1))[: order + 1]
    r[0] *= 1.0 + 1e-9  # the white floor of lpc_autocorrelation: well conditioned at order 200
    a = np.concatenate([[1.0], sl.solve_toeplitz(r[:order], -r[1:order + 1])])
    if not is_stable(a):  # rounding at extreme dynamic range: the recursion keeps |k| < 1
        return levinson(r, order)
    return a, float(r[0] + np.dot(a[1:], r[1:order + 1]))
