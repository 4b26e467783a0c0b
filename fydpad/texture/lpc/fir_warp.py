"""The FIR structure's lags at the speed the surface passed at.

In a(k) = sum_j g_v(j) e(k - j) a surface line sits at f = v / lambda, so the current
filter on noise j samples old rings at the wrong frequency when the speed changes fast:
a stroke's start sprays a narrow line far from itself (corduroy: +10 dB at twice the
line). Lag j therefore uses the filter at the mean speed over that lag, beyond a slack:

    u_j = v(k) + phi_j (d_j - clip(d_j, -slack, slack)),   d_j = mean(v(k-j) .. v(k)) - v(k)

exact for a purely spatial response, unchanged at a constant speed or a hand's wander, and
continuous in the speeds (no switch to click). phi_j is 1 over the first half of the lags
and falls linearly to 0 at the last, where the plain response's tail takes over.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
WARP_LAGS = 512  # lags whose speed is warped; the response's energy is mostly in the first 256
#: A hand's wander stays within it over 0.5 s (dv/dt ~ 10 mm/s^2), a stroke's start does not.
WARP_SLACK_MM_S = 3.0


def lag_fade(lags: int) -> Array:
    """phi_j: 1 over the first half of the lags, then linearly to 0 at the last."""
    half = lags // 2
    return np.concatenate([np.ones(half), np.linspace(1.0, 0.0, lags - half)])


def lag_speeds(recent_mm_s: Array, slack_mm_s: float = WARP_SLACK_MM_S,
               fade: Array | None = None) -> tuple[Array, NDArray[np.bool_]]:
    """u_j from the newest speeds, newest first on the last axis, and whether any lag is
    warped (else the plain FIR applies exactly). ``fade``: :func:`lag_fade`, prebuilt."""
    n = recent_mm_s.shape[-1]
    d = np.cumsum(recent_mm_s, axis=-1)
    d *= 1.0 / np.arange(1.0, n + 1.0)
    d -= recent_mm_s[..., :1]
    warped = (d.max(axis=-1) > slack_mm_s) | (d.min(axis=-1) < -slack_mm_s)
    u = d - np.clip(d, -slack_mm_s, slack_mm_s)
    u *= lag_fade(n) if fade is None else fade
    u += recent_mm_s[..., :1]
    return u, warped


def table_position(speed_mm_s: Array, v0_mm_s: float, step_mm_s: float, rows: int
                   ) -> tuple[NDArray[np.int64], Array]:
    """The table's lower entry for each speed and the weight of the upper (clamped)."""
    x = np.clip((speed_mm_s - v0_mm_s) / step_mm_s, 0.0, rows - 1.0)
    k = np.minimum(x.astype(np.int64), rows - 2)
    return k, x - k


def warped_responses(fir: Array, v0_mm_s: float, step_mm_s: float, u_mm_s: Array) -> Array:
    """Each sample's response (..., n_fir) from its lag speeds (..., L): lag j < L from the
    table at u_j, later lags at u_{L-1} (the current speed)."""
    rows, n_fir = fir.shape
    lags = min(u_mm_s.shape[-1], n_fir)
    k, w = table_position(u_mm_s[..., :lags], v0_mm_s, step_mm_s, rows)
    j = np.arange(lags)
    g = np.empty((*u_mm_s.shape[:-1], n_fir))
    g[..., :lags] = (1.0 - w) * fir[k, j] + w * fir[k + 1, j]
    if n_fir > lags:
        kt, wt, jt = k[..., -1:], w[..., -1:], np.arange(lags, n_fir)
        g[..., lags:] = (1.0 - wt) * fir[kt, jt] + wt * fir[kt + 1, jt]
    return g
