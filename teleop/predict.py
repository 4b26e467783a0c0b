"""Estimate where the finger is *now* from the master's past samples.

The paper's slave held each 10 Hz sample (IV-B), so it trailed the finger by half a
sample period plus the arm's lag: ~3 mm MAE (eq. 6). At 30 Hz and 40 mm/s one frame
is still 1.3 mm, so the slave extrapolates: a least-squares polynomial (quadratic by
default, so tap turns are followed) over the last few samples, evaluated at the
current time plus the arm's own lag (feed-forward). Pure: times are passed in.
"""

from __future__ import annotations

from collections import deque

import numpy as np


class Predictor:
    """Polynomial extrapolation of a 3-D position over a sliding window of samples."""

    def __init__(self, window: int = 6, degree: int = 2, max_horizon_s: float = 0.12) -> None:
        if window < 1 or degree < 0:
            raise ValueError(f"window must be >= 1 and degree >= 0, got {window}, {degree}")
        self.window = window
        self.degree = degree
        self.max_horizon_s = max_horizon_s
        self._t: deque[float] = deque(maxlen=window)
        self._p: deque[np.ndarray] = deque(maxlen=window)

    def reset(self) -> None:
        """Forget the history (after a clutch or watchdog: never extrapolate across a gap)."""
        self._t.clear()
        self._p.clear()

    def __len__(self) -> int:
        return len(self._t)

    def add(self, t_s: float, p_mm: np.ndarray) -> None:
        """Add a sample taken at ``t_s`` (strictly later than the previous one)."""
        if self._t and t_s <= self._t[-1]:
            raise ValueError(f"sample time {t_s} not after the previous {self._t[-1]}")
        self._t.append(float(t_s))
        self._p.append(np.asarray(p_mm, dtype=float).copy())

    def latest(self) -> np.ndarray | None:
        return self._p[-1].copy() if self._p else None

    def predict(self, t_s: float) -> np.ndarray | None:
        """Position at ``t_s``; None without samples. Horizon clamped to max_horizon_s."""
        n = len(self._t)
        if n == 0:
            return None
        if n == 1 or self.degree == 0:
            return self._p[-1].copy()
        t = np.fromiter(self._t, float, n)
        t0 = t[-1]
        h = min(max(t_s - t0, 0.0), self.max_horizon_s)
        # Degree grows with the history (2 samples: a line), never above n - 2 so the fit
        # averages noise instead of interpolating it, except for the 2-sample line.
        deg = min(self.degree, max(1, n - 2))
        # Scale time to the window length: a well-conditioned Vandermonde matrix.
        scale = max(t0 - t[0], 1e-6)
        tau = (t - t0) / scale
        vander = np.vander(tau, deg + 1)
        coef, *_ = np.linalg.lstsq(vander, np.stack(self._p), rcond=None)
        return np.vander(np.array([h / scale]), deg + 1) @ coef

    def predict_flat(self, t_s: float) -> np.ndarray | None:
        """Like predict, as a flat (3,) array."""
        p = self.predict(t_s)
        return None if p is None else np.ravel(p)
