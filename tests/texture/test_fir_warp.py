"""The FIR structure's warp: each lag at the mean speed over it, beyond a slack (docs/texture.md,
"Speed changes in the FIR structure")."""

from __future__ import annotations

import numpy as np

from fydpad.texture.lpc.synthesis import (
    WARP_LAGS,
    WARP_SLACK_MM_S,
    lag_fade,
    lag_speeds,
    table_position,
    warped_responses,
)


def responses_along(fir: np.ndarray, v0_mm_s: float, step_mm_s: float,
                    speeds_mm_s: np.ndarray) -> np.ndarray:
    """Every sample's response (n, n_fir) along a speed trace, the speed before it held
    at the first: what the renderer applies, written plainly (it computes only the warped
    samples this way)."""
    v = np.asarray(speeds_mm_s, float)
    lags = min(WARP_LAGS, fir.shape[1])
    hv = np.concatenate([np.full(lags - 1, v[0]), v])
    recent = np.lib.stride_tricks.sliding_window_view(hv, lags)[:, ::-1]
    u, _ = lag_speeds(recent)
    k, w = table_position(v, v0_mm_s, step_mm_s, fir.shape[0])
    g = (1.0 - w[:, None]) * fir[k] + w[:, None] * fir[k + 1]  # the tail: u ends at v
    g[:, :lags] = warped_responses(fir[:, :lags], v0_mm_s, step_mm_s, u)
    return g


def _table(rows: int = 41, taps: int = 700) -> np.ndarray:
    """Distinct, smooth rows: a decaying sinusoid whose frequency grows with the row."""
    j = np.arange(taps)
    return np.vstack([np.exp(-j / 150.0) * np.cos(2 * np.pi * (0.01 + 0.002 * r) * j)
                      for r in range(rows)])


def test_a_constant_or_wandering_speed_keeps_the_plain_fir():
    recent = np.full(WARP_LAGS, 25.0)
    u, warped = lag_speeds(recent)
    assert not warped and np.array_equal(u, recent)
    # A hand's wander: +-2 mm/s at 1 Hz over the last 0.5 s stays within the slack.
    t = np.arange(WARP_LAGS) / 1000.0
    wander = 25.0 + 2.0 * np.sin(2 * np.pi * 1.0 * t)
    u, warped = lag_speeds(wander)
    assert not warped
    np.testing.assert_array_equal(u, np.full(WARP_LAGS, wander[0]))


def test_a_start_warps_the_old_lags_towards_the_speeds_they_were_made_at():
    # Newest first: 30 mm/s now, a ramp up from 0 over the last 250 ms.
    recent = np.concatenate([np.linspace(30.0, 0.0, 250), np.zeros(WARP_LAGS - 250)])
    u, warped = lag_speeds(recent)
    assert warped
    mean = np.cumsum(recent) / np.arange(1, WARP_LAGS + 1)
    fade = lag_fade(WARP_LAGS)
    # Each lag: its mean speed, less the slack, faded back to the current speed.
    expected = 30.0 + fade * np.minimum(mean - 30.0 + WARP_SLACK_MM_S, 0.0)
    np.testing.assert_allclose(u, expected, atol=1e-12)
    assert u[-1] == 30.0  # the fade ends at the current speed: the plain tail joins
    assert u[WARP_LAGS // 2 - 1] < 20.0  # the old lags really are slower


def test_the_warp_is_continuous_where_it_starts():
    """Just past the slack the lag speeds differ from the current one by the excess only:
    no switch, so no click where the warp engages."""
    for excess in (1e-9, 1e-3, 0.1):
        # 25 mm/s now, slower before: the oldest lag's mean is slack + excess below.
        drop = (WARP_SLACK_MM_S + excess) * WARP_LAGS / (WARP_LAGS - 1)
        recent = np.concatenate([[25.0], np.full(WARP_LAGS - 1, 25.0 - drop)])
        u, warped = lag_speeds(recent)
        assert warped
        assert np.max(np.abs(u - 25.0)) <= excess + 1e-9


def test_responses_along_a_constant_speed_are_the_plain_interpolated_table():
    fir = _table()
    v = np.full(50, 17.3)
    g = responses_along(fir, 10.0, 0.5, v)
    k, w = table_position(np.array([17.3]), 10.0, 0.5, fir.shape[0])
    plain = (1 - w[0]) * fir[k[0]] + w[0] * fir[k[0] + 1]
    np.testing.assert_allclose(g, np.broadcast_to(plain, g.shape), rtol=0, atol=1e-15)


def test_table_position_clamps_to_the_table():
    k, w = table_position(np.array([-5.0, 10.0, 30.0, 99.0]), 10.0, 0.5, 41)
    assert k.tolist() == [0, 0, 39, 39]
    np.testing.assert_allclose(w, [0.0, 0.0, 1.0, 1.0])
