"""Moving a fitted LPC model along the speed axis: the ``"stretch"`` interpolation.

Why. A texture's vibration is partly spatial: a surface feature of wavelength lambda
sounds at f = v / lambda, so its spectrum slides along the frequency axis as the speed
changes (paper III-B; the paper's linear interpolation and LSF interpolation only
cross-fade two fitted spectra). It is also partly temporal: the tool's resonance, the
sensor floor and the high-pass stay put. Per texture a warp exponent beta in [0, 1]
and a level exponent gamma are fitted from the model's own neighbouring speeds,

    log P(f; v) = log P_i(f * (v_i / v) ** beta) + gamma * log(v / v_i),

(beta = 1: purely spatial, 0: purely temporal), least squares over the fit band:
beta on every adjacent pair of fitted speeds in both directions (whether a surface
sounds spatially is a property of the surface), then gamma for each pair with that
beta (sandpaper_p80's power grows 20 dB from 20 to 30 mm/s and 8 dB from 30 to 40, as
its roughness band's edge crosses the tool's mode).

Each fitted model is the pooled spectrum of the runs within the fit tolerance of its
speed, so it already holds the speed variation of a stroke near that speed: within
``hold_mm_s`` of a fitted speed the fitted model is used unchanged (interpolating there
spreads the spectrum twice; measured: it is what kept the held-out LSD 0.1-1 dB above
the ceiling at the modelled speeds). Between the hold bands both neighbours are warped
from their band's edge to the speed, mixed in log power with a weight linear in speed,
and an all-pole model of the model's order is refitted to the mixed spectrum
(autocorrelation by inverse FFT, Levinson-Durbin). The Toeplitz matrix of a positive
spectrum is positive definite, so every refitted filter is stable (checked anyway).
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.linalg as sl
from numpy.typing import ArrayLike, NDArray

from fydpad.texture.lpc import is_stable, levinson

Array = NDArray[np.float64]
NFFT = 8192
BETAS = np.linspace(0.0, 1.0, 11)


def log_psd(polys: ArrayLike, sigma2: ArrayLike, nfft: int = NFFT) -> Array:
    """log(sigma^2 / |A(e^jw)|^2) on ``nfft // 2 + 1`` frequencies 0..fs/2, one row per model."""
    a = np.atleast_2d(np.asarray(polys, float))
    resp = np.fft.rfft(a, nfft, axis=1)
    return np.log(np.asarray(sigma2, float).reshape(-1, 1)) - np.log(np.abs(resp) ** 2)


def warp(log_p: Array, f_hz: Array, v_from: float, v_to: float, beta: float,
         gamma: float) -> Array:
    """The log spectrum at ``v_from`` moved to ``v_to`` (module equation); held past fs/2."""
    r = v_to / v_from
    return np.interp(f_hz * r ** -beta, f_hz, log_p) + gamma * np.log(r)


def fit_exponents(speeds_mm_s: Array, log_p: Array, f_hz: Array,
                  band_hz: tuple[float, float], betas: ArrayLike = BETAS) -> tuple[float, float]:
    """(beta, gamma) that best map each fitted spectrum onto its neighbours' (least squares)."""
    s = np.asarray(speeds_mm_s, float)
    if s.size < 2:
        return 1.0, 0.0
    sel = (f_hz >= band_hz[0]) & (f_hz <= band_hz[1])
    pairs = [(i, j) for k in range(s.size - 1) for i, j in ((k, k + 1), (k + 1, k))]
    best = (np.inf, 1.0, 0.0)
    for beta in np.atleast_1d(np.asarray(betas, float)):
        d = np.concatenate([log_p[j][sel] - warp(log_p[i], f_hz, s[i], s[j], beta, 0.0)[sel]
                            for i, j in pairs])
        lg = np.concatenate([np.full(int(sel.sum()), np.log(s[j] / s[i])) for i, j in pairs])
        gamma = float(np.dot(d, lg) / np.dot(lg, lg))
        err = float(np.mean((d - gamma * lg) ** 2))
        if err < best[0]:
            best = (err, float(beta), gamma)
    return best[1], best[2]


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


class SpeedWarp:
    """The ``"stretch"`` interpolation of a model's fitted (A, sigma^2) at any speed."""

    def __init__(self, speeds_mm_s: Array, polys: Array, sigma2: Array, fs_hz: float,
                 band_hz: tuple[float, float], hold_mm_s: float):
        self.speeds_mm_s = np.asarray(speeds_mm_s, float)
        self.polys = np.asarray(polys, float)
        self.sigma2 = np.asarray(sigma2, float)
        self.order = self.polys.shape[1] - 1
        self.f_hz = np.arange(NFFT // 2 + 1) * fs_hz / NFFT
        self.log_p = log_psd(self.polys, self.sigma2)
        s = self.speeds_mm_s
        self.beta, self.gamma = fit_exponents(s, self.log_p, self.f_hz, band_hz)
        self.pairs = [fit_exponents(s[k:k + 2], self.log_p[k:k + 2], self.f_hz, band_hz,
                                    [self.beta]) for k in range(max(s.size - 1, 0))]
        self.hold_mm_s = float(hold_mm_s)

    def __call__(self, speed_mm_s: float) -> tuple[Array, float]:
        s = self.speeds_mm_s
        v = float(speed_mm_s)
        if s.size == 1 or v <= s[0] or v >= s[-1]:  # clamped (the renderer fades below)
            i = 0 if s.size == 1 or v <= s[0] else s.size - 1
            return self.polys[i].copy(), float(self.sigma2[i])
        j = int(np.searchsorted(s, v))
        i = j - 1
        h = min(self.hold_mm_s, 0.45 * (s[j] - s[i]))
        if v <= s[i] + h:
            return self.polys[i].copy(), float(self.sigma2[i])
        if v >= s[j] - h:
            return self.polys[j].copy(), float(self.sigma2[j])
        w = (v - s[i] - h) / (s[j] - s[i] - 2 * h)
        beta, gamma = self.pairs[i]
        mixed = ((1.0 - w) * warp(self.log_p[i], self.f_hz, s[i] + h, v, beta, gamma)
                 + w * warp(self.log_p[j], self.f_hz, s[j] - h, v, beta, gamma))
        return ar_from_log_psd(mixed, self.order)


# ------------------------------------------------------------ speed-normalised fitting
CHUNK = 1024  # samples per periodogram chunk (its speed is normalised sample by sample)
_UP = 4  # oversampling of the time warp (linear interpolation at 4 kHz is flat to 500 Hz)


def normalise_speed(x: Array, speed_mm_s: Array, v0_mm_s: float, beta: float,
                    gamma: float) -> tuple[Array, float]:
    """``x`` recorded at ``speed_mm_s`` resampled as if scanned at a constant ``v0_mm_s``.

    The module equation done on the signal: time runs at dtau/dt = (v / v0) ** beta (beta
    = 1: exactly in space, a feature of wavelength lambda at v0 / lambda), the level
    scaled by (v0 / v) ** (gamma / 2). Band-limited (FFT up-sampling x4, linear
    interpolation, brick-wall back to the rate). Returns (y, top) with ``top`` the
    share of the band that holds data (a stretch leaves the band above
    fs/2 * v0 / v_max empty).
    """
    v = np.maximum(np.asarray(speed_mm_s, float), 0.2 * v0_mm_s)
    r = (v / v0_mm_s) ** beta
    xs = np.asarray(x, float) * (v0_mm_s / v) ** (gamma / 2)
    xu = np.fft.irfft(np.fft.rfft(xs), xs.size * _UP) * _UP
    tau = np.concatenate([[0.0], np.cumsum(np.repeat(r, _UP)[:-1])])
    m = int(tau[-1]) // _UP
    yu = np.interp(np.arange(m * _UP), tau, xu)
    return np.fft.irfft(np.fft.rfft(yu)[: m // 2 + 1], m) / _UP, float(1.0 / r.max())


def normalised_spectrum(x: Array, speed_mm_s: Array, v0_mm_s: float, beta: float,
                        gamma: float, nfft: int = NFFT) -> tuple[Array, float]:
    """Power spectrum (``nfft // 2 + 1`` bins, mean = signal power) of one speed run moved
    to ``v0_mm_s`` chunk by chunk (Hann); bins above a chunk's data keep its unwarped
    periodogram (there the vibration is the tool's and the sensor's, not the surface's).
    Returns (sum of chunk spectra weighted by their length, total length)."""
    n = x.size
    edges = np.linspace(0, n, max(1, round(n / CHUNK)) + 1).astype(int)
    f = np.arange(nfft // 2 + 1) / nfft  # cycles per sample
    acc = np.zeros(f.size)
    for a, b in itertools.pairwise(edges.tolist()):
        y, top = normalise_speed(x[a:b], speed_mm_s[a:b], v0_mm_s, beta, gamma)
        spec = []
        for s in (y, x[a:b]):
            w = np.hanning(s.size)
            spec.append(np.abs(np.fft.rfft(s * w, nfft)) ** 2 / max(np.dot(w, w), 1e-30))
        acc += (b - a) * np.where(f < 0.49 * top, spec[0], spec[1])
    return acc, float(n)
