"""Streaming rational polyphase resampler.

y[n] = sum_j h[p + j L] x[i0 - j], with i0 = floor(n M / L), p = (n M) mod L: the
upsample-by-L, FIR, downsample-by-M chain of ``scipy.signal.upfirdn``, evaluated only at
the kept outputs. The FIR history (the last K-1 inputs) is carried across blocks, so
block-wise output equals one-shot output. The filter is scipy.signal.resample_poly's
default: Kaiser (beta 5) windowed sinc, 20 max(L, M) + 1 taps, cutoff at the lower of the
two Nyquist rates, gain L.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from numpy.typing import NDArray
from scipy.signal import firwin


def ratio(rate_in_hz: float, rate_out_hz: float) -> tuple[int, int]:
    """(up, down) in lowest terms, e.g. 1000 -> 44100 gives (441, 10)."""
    fr = Fraction(rate_out_hz).limit_denominator(100000) / Fraction(rate_in_hz).limit_denominator(
        100000)
    return fr.numerator, fr.denominator


def design_filter(up: int, down: int) -> NDArray[np.float64]:
    """Anti-imaging/anti-aliasing FIR, identical to resample_poly's default window."""
    max_rate = max(up, down)
    half_len = 10 * max_rate
    return firwin(2 * half_len + 1, 1.0 / max_rate, window=("kaiser", 5.0)) * up


class Resampler:
    """Stateful resampler from ``rate_in_hz`` to ``rate_out_hz``; call :meth:`process` per block."""

    def __init__(self, rate_in_hz: float, rate_out_hz: float,
                 h: NDArray[np.float64] | None = None) -> None:
        self.up, self.down = ratio(rate_in_hz, rate_out_hz)
        self.h = design_filter(self.up, self.down) if h is None else np.asarray(h, float)
        k = -(-len(self.h) // self.up)
        padded = np.zeros(k * self.up)
        padded[: len(self.h)] = self.h
        self._poly = padded.reshape(k, self.up).T.copy()  # [phase, tap]
        self._k = k
        self._hist = np.zeros(k - 1)
        self._n_in = 0   # inputs consumed so far
        self._n_out = 0  # outputs produced so far

    @property
    def delay_in_samples(self) -> float:
        """Group delay of the linear-phase filter, in input samples."""
        return (len(self.h) - 1) / 2 / self.up

    def process(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Resample the next block; returns every output whose input is available."""
        x = np.asarray(x, dtype=np.float64)
        buf = np.concatenate((self._hist, x))
        base = self._n_in - (self._k - 1)  # global input index of buf[0]
        n_in_end = self._n_in + len(x)
        n_end = -(-n_in_end * self.up // self.down)  # outputs n with n*M//L <= n_in_end-1
        n = np.arange(self._n_out, n_end, dtype=np.int64)
        m = n * self.down
        i0, p = m // self.up, m % self.up
        idx = (i0 - base)[:, None] - np.arange(self._k)[None, :]
        y = np.einsum("ij,ij->i", self._poly[p], buf[idx]) if len(n) else np.zeros(0)
        self._hist = buf[len(buf) - (self._k - 1):] if self._k > 1 else np.zeros(0)
        self._n_in, self._n_out = n_in_end, n_end
        return y
