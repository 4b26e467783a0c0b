"""The FIR structure's lags at the speed the surface passed at (docs/texture.md, "Speed
changes in the FIR structure: each lag at the speed it was made at").

The FIR structure writes the output as a(k) = sum_j g_v(j) e(k - j), with g_v the impulse
response of the table filter at the current speed v. A surface feature is spatial: its
line sits at f = v / lambda, and the response at lag j rings at the frequency of the
speed that noise sample has been travelling at. Applying the *current* filter to noise j
samples old rings it at v(k) / lambda over the whole lag, so when the speed changes fast
(a finger starting a stroke: 0 to 30 mm/s in 0.25 s) the phase at lag j is off by
2 pi j (v(k) - vbar_j) / (lambda fs) and a narrow line sprays energy far from itself
(measured on corduroy, 2.5 mm ribs: +10 dB at twice the line's frequency, 24 Hz at
30 mm/s, from the 0.25 s ramps at a stroke's ends alone; one held-out stroke scored 0.14
to 0.89 dB over the ceiling depending on the noise seed).

Here lag j uses the filter at the mean speed over that lag,

    vbar_j = mean(v(k - j) ... v(k)),      (the distance travelled over the lag / its time)

which is exact for a purely spatial response, g_v(j) = c(v) u(v j / fs), and unchanged
at a constant speed. Only the excess of vbar_j - v(k) beyond ``slack_mm_s`` is used:

    u_j = v(k) + phi_j (d_j - clip(d_j, -slack, slack)),   d_j = vbar_j - v(k),

so a hand's wander (a few mm/s over the horizon) keeps the plain FIR and its fast
paths, and a start or stop gets the warp; u is continuous in the speeds, so there is no
switch to click at. phi_j is 1 over the first half of the warped lags and falls
linearly to 0 at the last (lags 256 and 511 of ``WARP_LAGS`` = 512, or of the response's
length when that is shorter), where the plain response's tail (at the current speed)
takes over without a step; the responses' energy is mostly in the first 256 lags (90-99 % on the
generator's textures).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Lags whose speed is warped (the second half fading back to the current speed).
WARP_LAGS = 512
#: Deviation of a lag's mean speed from the current one left unwarped (mm/s): a hand's
#: wander stays within it over 0.5 s (dv/dt ~ 10 mm/s^2), a stroke's start does not.
WARP_SLACK_MM_S = 3.0


def lag_fade(lags: int) -> Array:
    """phi_j: 1 over the first half of the warped lags, then linearly to 0 at the last,
    so the warped response joins the plain one's tail without a step (a response cut
    into bands of different speeds leaks like a stepwise table)."""
    half = lags // 2
    return np.concatenate([np.ones(half), np.linspace(1.0, 0.0, lags - half)])


def lag_speeds(recent_mm_s: Array, slack_mm_s: float = WARP_SLACK_MM_S,
               fade: Array | None = None) -> tuple[Array, NDArray[np.bool_]]:
    """Each lag's speed u_j (module docstring) from the newest speeds, newest first, on
    the last axis (``recent_mm_s[..., 0]`` is the current speed); and whether any lag
    differs from the current speed (else the plain FIR applies, exactly). ``fade``:
    :func:`lag_fade` of the window's length, given to save building it."""
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
    """The FIR table's lower entry and the weight of the upper one for each speed (the
    renderer's linear interpolation between entries, clamped to the table)."""
    x = np.clip((speed_mm_s - v0_mm_s) / step_mm_s, 0.0, rows - 1.0)
    k = np.minimum(x.astype(np.int64), rows - 2)
    return k, x - k


def warped_responses(fir: Array, v0_mm_s: float, step_mm_s: float, u_mm_s: Array) -> Array:
    """The response each sample applies, lag by lag: (..., n_fir) from the lag speeds
    (..., L) of :func:`lag_speeds`; lag j < L from the table at u_j, later lags at
    u_{L-1} (the current speed: the fade ends there)."""
    rows, n_fir = fir.shape
    lags = min(u_mm_s.shape[-1], n_fir)
    k, w = table_position(u_mm_s[..., :lags], v0_mm_s, step_mm_s, rows)
    j = np.arange(lags)
    g = np.empty((*u_mm_s.shape[:-1], n_fir))
    g[..., :lags] = (1.0 - w) * fir[k, j] + w * fir[k + 1, j]
    if n_fir > lags:
        kt, wt = k[..., -1:], w[..., -1:]
        g[..., lags:] = (1.0 - wt) * fir[kt, np.arange(lags, n_fir)] \
            + wt * fir[kt + 1, np.arange(lags, n_fir)]
    return g


def responses_along(fir: Array, v0_mm_s: float, step_mm_s: float, speeds_mm_s: Array,
                    before_mm_s: Array | None = None, lags: int = WARP_LAGS,
                    slack_mm_s: float = WARP_SLACK_MM_S) -> Array:
    """Every sample's response (n, n_fir) along a speed trace, the ``lags`` - 1 speeds
    ``before_mm_s`` (oldest first; default: the first speed held) in front: what the
    renderer applies, written plainly (for tests and plots; the renderer computes only
    the warped samples this way)."""
    v = np.asarray(speeds_mm_s, float)
    if v.size == 0:
        return np.zeros((0, fir.shape[1]))
    lags = min(lags, fir.shape[1])
    pre = np.full(lags - 1, v[0]) if before_mm_s is None else np.asarray(before_mm_s, float)
    if pre.size < lags - 1:
        raise ValueError(f"before_mm_s holds {pre.size} speeds; the first sample's lags need "
                         f"{lags - 1}")
    hv = np.concatenate([pre[pre.size - (lags - 1):] if lags > 1 else pre[:0], v])
    recent = np.lib.stride_tricks.sliding_window_view(hv, lags)[:, ::-1]
    u, _ = lag_speeds(recent, slack_mm_s)
    return warped_responses(fir, v0_mm_s, step_mm_s, u)
