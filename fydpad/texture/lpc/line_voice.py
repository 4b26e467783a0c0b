"""A line spectrum (lines.py) at the output rate, from one wavetable per grid speed:

    a_lines(k) = sum_n A_n(v_k) cos(2 pi n phi_k + psi_n),   phi_k = phi_{k-1} + v_k / (fs lambda)

Each sample reads the table at the phase phi (linear between points) and mixes the two
grid speeds around v linearly, so the lines glide with the speed and never click. Above
the fastest row pitch and level hold (the table is in band only up to it). ``tick`` (no
allocation) and ``block`` give the same samples: the phase is one running sum in both.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad.texture.lpc.lines import LineSpectrum

Array = NDArray[np.float64]


class LineVoice:
    """The lines of one texture; ``phase`` in cycles of the period, unbounded."""

    def __init__(self, spectrum: LineSpectrum, fs_hz: float):
        self.spectrum = spectrum
        self.table = np.ascontiguousarray(spectrum.wavetable())  # (m, points + 1)
        self.points = self.table.shape[1] - 1
        v = spectrum.v_mm_s
        self._v0, self._v_top = float(v[0]), float(v[-1])
        self._inv_step = 1.0 / float(v[1] - v[0]) if v.size > 1 else 0.0
        self._last_row = float(v.size - 1)
        if v.size == 1:  # one speed: two equal rows keep the mixing uniform
            self.table = np.vstack([self.table, self.table])
            self._last_row = 1.0
        self._k_top = int(self._last_row) - 1  # the lower of the last two rows
        self._cycles_per_sample = 1.0 / (float(fs_hz) * float(spectrum.period_mm))
        self._rows = list(self.table)  # views made once: no view per tick
        self.phase = 0.0

    def reset(self) -> None:
        self.phase = 0.0

    def tick(self, speed_mm_s: float) -> float:
        """One sample at this speed (mm/s; finite, >= 0)."""
        if speed_mm_s > self._v_top:
            speed_mm_s = self._v_top
        ph = self.phase + speed_mm_s * self._cycles_per_sample
        self.phase = ph
        x = min(max((speed_mm_s - self._v0) * self._inv_step, 0.0), self._last_row)
        k = min(int(x), self._k_top)
        w = x - k
        p = (ph - math.floor(ph)) * self.points
        i = int(p)
        fr = p - i
        r0, r1 = self._rows[k], self._rows[k + 1]
        a0, a1 = r0.item(i), r0.item(i + 1)
        b0, b1 = r1.item(i), r1.item(i + 1)
        a = a0 + fr * (a1 - a0)
        b = b0 + fr * (b1 - b0)
        return a + w * (b - a)

    def block(self, speed_mm_s: ArrayLike) -> Array:
        """Samples for a speed trace (finite, >= 0): ``tick`` sample by sample."""
        v = np.minimum(np.asarray(speed_mm_s, float), self._v_top)
        if v.size == 0:
            return np.zeros(0)
        ph = np.cumsum(np.concatenate([[self.phase], v * self._cycles_per_sample]))[1:]
        self.phase = float(ph[-1])
        x = np.clip((v - self._v0) * self._inv_step, 0.0, self._last_row)
        k = np.minimum(x.astype(np.int64), self._k_top)
        w = x - k
        p = (ph - np.floor(ph)) * self.points
        i = p.astype(np.int64)
        fr = p - i
        t = self.table
        a = t[k, i] + fr * (t[k, i + 1] - t[k, i])
        b = t[k + 1, i] + fr * (t[k + 1, i + 1] - t[k + 1, i])
        return a + w * (b - a)
