"""The live, causal inverse of the chain: a minimum-phase FIR.

The FFT form of eqs. 2-4 needs the whole signal; the 1 kHz render loop needs a causal
filter. A minimum-phase filter with the regularised inverse's *magnitude* is causal and
stable, and its inverse is too, so it equalises the spectrum the finger feels; the
chain's excess phase (its delays) is left alone, which a spectrum does not see. Design
by the real cepstrum (homomorphic): fold the cepstrum of log|inv| onto positive
quefrencies, exponentiate, and keep the first ``ntaps`` taps (a half-Hann taper on the
last eighth keeps the truncation from rippling the response).

Two paths over the same taps that agree sample for sample: :func:`fir_filter` (block,
state in and out as scipy's ``zi``/``zf``: here the last ``ntaps - 1`` inputs, oldest
first) and :class:`InverseFilter` (``tick`` per sample, no array allocated per tick).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def min_phase_fir(freqs_hz: Array, magnitude: Array, rate_hz: float, ntaps: int = 128,
                  nfft: int = 8192) -> Array:
    """``ntaps`` FIR taps with |H| ~ ``magnitude`` (given at ``freqs_hz``, held beyond
    its ends) and minimum phase, by the folded real cepstrum on an ``nfft`` grid."""
    f = np.fft.rfftfreq(nfft, 1.0 / rate_hz)
    logmag = np.interp(f, freqs_hz, np.log(np.maximum(magnitude, 1e-12)))
    cep = np.fft.irfft(logmag, nfft)
    fold = np.zeros(nfft)
    fold[0] = cep[0]
    fold[1:nfft // 2] = 2.0 * cep[1:nfft // 2]
    fold[nfft // 2] = cep[nfft // 2]
    h = np.fft.irfft(np.exp(np.fft.rfft(fold)), nfft)[:ntaps].copy()
    tail = max(ntaps // 8, 1)
    h[ntaps - tail:] *= 0.5 + 0.5 * np.cos(np.pi * np.arange(1, tail + 1) / tail)
    return h


def fir_filter(taps: ArrayLike, x: ArrayLike, zi: ArrayLike | None = None
               ) -> tuple[Array, Array]:
    """Block FIR: y[k] = sum_j taps[j] x[k - j]; ``zi`` = the previous ``ntaps - 1``
    inputs (oldest first, zeros if None); returns (y, zf) in the same format."""
    h = np.asarray(taps, np.float64)
    x = np.asarray(x, np.float64)
    zi = np.zeros(h.size - 1) if zi is None else np.asarray(zi, np.float64)
    if zi.shape != (h.size - 1,):
        raise ValueError(f"zi must have shape ({h.size - 1},), got {zi.shape}")
    ext = np.concatenate([zi, x])
    return np.convolve(ext, h, "valid"), ext[ext.size - (h.size - 1):].copy()


class InverseFilter:
    """Per-sample FIR for the 1 kHz loop: a doubled ring buffer whose ``ntaps`` windows
    (views made once, here) are dotted with the reversed taps, so a tick writes two
    floats and makes one dot product."""

    def __init__(self, taps: ArrayLike) -> None:
        h = np.asarray(taps, np.float64)
        n = h.size
        self.ntaps = n
        self._rev = h[::-1].copy()
        self._buf = np.zeros(2 * n)
        # After writing at p (and p + n), the last n inputs, oldest first: buf[p+1:p+n+1].
        self._windows = [self._buf[p + 1:p + n + 1] for p in range(n)]
        self._p = n - 1

    @property
    def taps(self) -> Array:
        return self._rev[::-1].copy()

    def set_taps(self, taps: ArrayLike) -> None:
        """Switch to other taps of the same length (another stiffness), history kept."""
        h = np.asarray(taps, np.float64)
        if h.size != self.ntaps:
            raise ValueError(f"taps must have {self.ntaps} values, got {h.size}")
        self._rev[:] = h[::-1]

    def tick(self, x: float) -> float:
        """One sample in, one out."""
        p = self._p + 1
        if p == self.ntaps:
            p = 0
        self._p = p
        buf = self._buf
        buf[p] = x
        buf[p + self.ntaps] = x
        return float(self._rev.dot(self._windows[p]))

    def state(self) -> Array:
        """The last ``ntaps - 1`` inputs, oldest first (``fir_filter``'s zi)."""
        return self._windows[self._p][1:].copy()

    def set_state(self, zi: ArrayLike) -> None:
        """Load a history in ``fir_filter``'s zi format."""
        zi = np.asarray(zi, np.float64)
        n = self.ntaps
        if zi.shape != (n - 1,):
            raise ValueError(f"zi must have shape ({n - 1},), got {zi.shape}")
        self._p = n - 1
        self._buf[:] = 0.0
        self._buf[n + 1:2 * n] = zi  # window at p = n - 1 is buf[n:2n]; its newest slot
        self._buf[1:n] = zi          # mirrors: buf[k] == buf[k + n]

    def reset(self) -> None:
        self._buf[:] = 0.0
