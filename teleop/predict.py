"""Estimate where the finger is *now* from the master's past samples.

The paper's slave held each 10 Hz sample (IV-B), so it trailed the finger by half a
sample period plus the arm's lag: ~3 mm MAE (eq. 6). At 30 Hz and 40 mm/s one frame
is still 1.3 mm, so the slave extrapolates: a least-squares polynomial (quadratic by
default, so tap turns are followed) over the last few samples, evaluated at the
current time plus the arm's own lag (feed-forward). Pure: times are passed in.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

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


# --------------------------------------------------------------------------- Kalman


def ca_transition(dt_s: float, jerk_psd: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-acceleration model over ``dt_s``: state (p, v, a), white jerk of power
    spectral density ``jerk_psd`` (mm^2/s^5). Returns F and the process noise Q."""
    d = dt_s
    f = np.array([[1.0, d, d * d / 2], [0.0, 1.0, d], [0.0, 0.0, 1.0]])
    q = jerk_psd * np.array([[d**5 / 20, d**4 / 8, d**3 / 6],
                             [d**4 / 8, d**3 / 3, d**2 / 2],
                             [d**3 / 6, d**2 / 2, d]])
    return f, q


def kalman_step(x: np.ndarray, p: np.ndarray, dt_s: float, z_mm: float, noise_mm: float,
                jerk_psd: float) -> tuple[np.ndarray, np.ndarray, float]:
    """One predict + update of the constant-acceleration filter of one axis: state ``x``
    (3,) and covariance ``p`` (3, 3) in, the updated pair out (as scipy's zi/zf), with
    the likelihood of the measurement under the prediction (for the IMM's weights)."""
    f, q = ca_transition(dt_s, jerk_psd)
    x = f @ x
    p = f @ p @ f.T + q
    s = p[0, 0] + noise_mm * noise_mm
    nu = z_mm - x[0]
    k = p[:, 0] / s
    x = x + k * nu
    p = p - np.outer(k, p[0, :])
    return x, 0.5 * (p + p.T), math.exp(-0.5 * nu * nu / s) / math.sqrt(2 * math.pi * s)


@dataclass
class IMMState:
    """State of the interacting multiple model filter of one axis: per model, the state
    (p, v, a) and its covariance, and the models' probabilities."""

    x: np.ndarray  # (models, 3)
    p: np.ndarray  # (models, 3, 3)
    mu: np.ndarray  # (models,)


def imm_start(z_mm: float, noise_mm: float, n_models: int, v0_mm_s: float = 100.0,
              a0_mm_s2: float = 2000.0, mu0: Sequence[float] | None = None) -> IMMState:
    """The filter at its first sample: there, at rest, velocity and acceleration unknown;
    the models' probabilities ``mu0`` (default: equal)."""
    p0 = np.diag([noise_mm * noise_mm, v0_mm_s**2, a0_mm_s2**2])
    mu = np.full(n_models, 1.0 / n_models) if mu0 is None else np.asarray(mu0, float)
    return IMMState(np.tile([z_mm, 0.0, 0.0], (n_models, 1)), np.tile(p0, (n_models, 1, 1)),
                    mu / mu.sum())


def transition_matrix(stay: float | Sequence[float], n_models: int) -> np.ndarray:
    """Markov matrix of the models: ``stay[i]`` on the diagonal (one value: all models),
    the rest of each row shared by the other models."""
    st = np.broadcast_to(np.asarray(stay, float), (n_models,))
    trans = np.repeat(((1.0 - st) / max(n_models - 1, 1))[:, None], n_models, axis=1)
    np.fill_diagonal(trans, st)
    return trans


def imm_step(st: IMMState, dt_s: float, z_mm: float, noise_mm: float,
             jerk_psd: tuple[float, ...], stay: float | Sequence[float]) -> IMMState:
    """One IMM cycle (Blom & Bar-Shalom): mix, filter with each model, re-weight by
    the models' likelihoods. ``stay``: probability that the motion keeps its model
    from one sample to the next (per model, or one for all)."""
    m = len(jerk_psd)
    trans = transition_matrix(stay, m)
    cbar = trans.T @ st.mu
    w = trans * st.mu[:, None] / cbar[None, :]  # w[i, j]: model i's share in j's start
    # Mixing and one Kalman step (kalman_step) for all models at once: ~1.7x faster than
    # a loop over the models, which matters at 1 kHz (docs/teleop.md).
    x0 = w.T @ st.x  # (j, 3)
    d = st.x[None, :, :] - x0[:, None, :]  # (j, i, 3)
    p0 = np.einsum("ij,jikl->jkl", w, st.p[None] + d[..., :, None] * d[..., None, :])
    f, q1 = ca_transition(dt_s, 1.0)
    x = x0 @ f.T
    p = f @ p0 @ f.T + np.asarray(jerk_psd, float)[:, None, None] * q1
    s = p[:, 0, 0] + noise_mm * noise_mm
    nu = z_mm - x[:, 0]
    k = p[:, :, 0] / s[:, None]
    x = x + k * nu[:, None]
    p = p - k[:, :, None] * p[:, None, 0, :]
    like = np.exp(-0.5 * nu * nu / s) / np.sqrt(2 * math.pi * s)
    mu = like * cbar
    total = float(mu.sum())
    return IMMState(x, 0.5 * (p + p.transpose(0, 2, 1)), mu / total if total > 1e-300 else cbar)


def imm_predict(st: IMMState, h_s: float) -> float:
    """Position ``h_s`` after the last sample: each model's extrapolation, weighted."""
    return float(st.mu @ (st.x[:, 0] + st.x[:, 1] * h_s + st.x[:, 2] * h_s * h_s / 2))


class IMMPredictor:
    """Where the indentation is now: an IMM of constant-acceleration Kalman filters.

    A polynomial through the last few samples hands their noise on amplified (the IR
    indentation's ~0.3-0.5 mm); a smooth filter misses a tap's turn. The IMM runs
    calm models (small jerk) and a quick one (large jerk) side by side and weights them
    by how well each predicted the last samples: smooth while the finger rests or
    slides, quick through a tap. Same interface as ``Predictor`` (one axis per entry).

    ``stay``: per model (or one for all), the probability of keeping it from one sample
    to the next; ``start``: the models' probabilities at the first sample (default
    equal). The slave starts each contact from the lifted sample with the quick model
    likely (a touch-down is the start of a press) and keeps the calm model sticky, so
    a slide is not taken for a press on the IR noise (docs/teleop.md).
    """

    def __init__(self, noise_mm: float, jerk_psd: tuple[float, ...],
                 stay: float | Sequence[float] = 0.98, max_horizon_s: float = 0.12,
                 start: Sequence[float] | None = None) -> None:
        m = len(jerk_psd)
        stay_arr = np.atleast_1d(np.asarray(stay, float))
        if stay_arr.size not in (1, m):
            raise ValueError(f"prediction.mode_stay has {stay_arr.size} values for the {m} "
                             f"models of prediction.jerk_psd_z {tuple(jerk_psd)}: give one "
                             "per model, or one for all")
        stays = np.broadcast_to(stay_arr, (m,)) if m else np.array([])
        if (noise_mm <= 0 or not m or min(jerk_psd) <= 0
                or not np.all((stays > 0) & (stays <= 1))):
            raise ValueError(f"IMM needs noise > 0, jerks > 0 and 0 < stay <= 1, got "
                             f"{noise_mm}, {jerk_psd}, {stay}")
        if start is not None and (len(start) != m or min(start) < 0 or sum(start) <= 0):
            raise ValueError(f"prediction.mode_start must be {m} values >= 0 with a positive "
                             f"sum, one per model of prediction.jerk_psd_z, got {start}")
        self.noise_mm = float(noise_mm)
        self.jerk_psd = tuple(float(j) for j in jerk_psd)
        self.stay = tuple(float(v) for v in stays)
        self.start = None if start is None else tuple(float(v) for v in start)
        self.max_horizon_s = max_horizon_s
        self.reset()

    def reset(self) -> None:
        self._t: float | None = None
        self._n = 0
        self._st: list[IMMState] = []
        self._last: np.ndarray | None = None

    def __len__(self) -> int:
        return self._n

    def add(self, t_s: float, p_mm: np.ndarray) -> None:
        z = np.ravel(np.asarray(p_mm, dtype=float))
        if self._t is None:
            self._st = [imm_start(zi, self.noise_mm, len(self.jerk_psd), mu0=self.start)
                        for zi in z]
        elif t_s <= self._t:
            raise ValueError(f"sample time {t_s} not after the previous {self._t}")
        else:
            self._st = [imm_step(st, t_s - self._t, zi, self.noise_mm, self.jerk_psd, self.stay)
                        for st, zi in zip(self._st, z, strict=True)]
        self._t = float(t_s)
        self._n += 1
        self._last = z.copy()

    def latest(self) -> np.ndarray | None:
        return None if self._last is None else self._last.copy()

    def predict_flat(self, t_s: float) -> np.ndarray | None:
        """Position at ``t_s`` as a flat array; None without samples."""
        if self._t is None:
            return None
        h = min(max(t_s - self._t, 0.0), self.max_horizon_s)
        return np.array([imm_predict(st, h) for st in self._st])

    def predict(self, t_s: float) -> np.ndarray | None:
        p = self.predict_flat(t_s)
        return None if p is None else p[None, :]
