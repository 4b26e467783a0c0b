"""Eq. 5 synthesis: per-sample and block paths, silence, fade, clamp, continuity."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.texture.lpc import ar_psd, h_from_poly, lpc_autocorrelation
from fydpad.texture.model_file import TextureModel
from fydpad.texture.synthesis import CentroidSpeed, TextureRenderer, synthesize


@pytest.fixture(scope="module")
def model() -> TextureModel:
    rng = np.random.default_rng(1)
    hs, s2 = [], []
    for f in (60, 120, 180, 240):
        b, a = ss.butter(2, [f - 15, f + 15], "bandpass", fs=1000)
        x = ss.lfilter(b, a, rng.standard_normal(8000)) + 0.01 * rng.standard_normal(8000)
        aa, v = lpc_autocorrelation([x], 60)
        hs.append(h_from_poly(aa))
        s2.append(v)
    return TextureModel("bands", 1000.0, np.array([10.0, 20, 30, 40]), np.vstack(hs),
                        np.array(s2))


def test_tick_and_block_give_the_same_samples(model):
    n = 2500
    v = np.concatenate([np.linspace(0, 45, 1500), np.full(1000, 25.0)])
    c = np.ones(n, bool)
    c[1700:1800] = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r1 = TextureRenderer(model, seed=5, drive_filter=True)
        r2 = TextureRenderer(model, seed=5, drive_filter=True)
        yb = np.concatenate([r1.block(v[:700], c[:700]), r1.block(v[700:], c[700:])])
        yt = np.array([r2.tick(float(s), bool(k)) for s, k in zip(v, c, strict=True)])
    np.testing.assert_allclose(yb, yt, atol=1e-12)


def test_silent_without_contact_or_when_still(model):
    r = TextureRenderer(model, seed=0)
    r.warmup(25.0)
    r.block(25.0, True, 200)
    assert np.all(r.block(25.0, False, 2000)[200:] == pytest.approx(0.0, abs=1e-9))
    r.block(25.0, True, 200)
    assert np.all(np.abs(r.block(0.0, True, 2000)[200:]) < 1e-9)


def test_fade_below_slowest_model_and_clamp_warns_once(model):
    r = TextureRenderer(model, seed=0)
    # The slowest model (10 mm/s, fitted within 5 mm/s) holds down to 5 mm/s, then fades.
    assert r.target_gain(2.5, True) == pytest.approx(0.5)
    assert r.target_gain(6.0, True) == 1.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r.block(55.0, True, 100)
        r.block(60.0, True, 100)
        r.tick(70.0, True)
    assert len([w for w in caught if "clamped" in str(w.message)]) == 1
    assert r.clamped


def test_model_change_has_no_click(model):
    """Across a speed step the recursion continues: no jump beyond the signal's own."""
    r = TextureRenderer(model, seed=3, ramp_s=1e-6)
    r.warmup(10.0)
    v = np.r_[np.full(3000, 10.0), np.full(3000, 40.0)]
    y = r.block(v, True)
    d = np.abs(np.diff(y))
    assert d[2995:3005].max() < 4 * np.percentile(d, 99)


def test_synthesized_spectrum_follows_model(model):
    y = synthesize(model, np.full(60_000, 30.0), seed=2)
    f, p = ss.welch(y, 1000.0, nperseg=250)
    sel = (f > 20) & (f < 480)
    ref = ar_psd(model.poly(2), model.sigma2[2], f[sel], 1000.0)
    assert np.sqrt(np.mean((10 * np.log10(p[sel] / ref)) ** 2)) < 1.0


def test_centroid_speed_at_1khz_from_30hz_positions():
    cs = CentroidSpeed()
    speeds = []
    for k in range(2000):  # 2 s at 1 kHz, camera every 33 ticks, finger at 20 mm/s
        t = k / 1000.0
        if k % 33 == 0:
            cs.position(t, 20.0 * t, 0.0, True)
        speeds.append(cs.tick(1e-3))
    assert speeds[-1] == pytest.approx(20.0, rel=0.02)
    assert max(np.abs(np.diff(speeds[500:]))) < 0.5  # smooth, not a 30 Hz staircase
    cs.position(2.0, 40.0, 0.0, False)
    assert cs.tick() == 0.0


def test_switching_at_the_speed_rate_stays_bounded():
    """A fitted high-dynamic-range texture, the speed jumping anywhere every 5 ms: the
    switched filter must not run away (a stable filter each is not enough; without the
    history cap this reaches 1e60). Transients of ~10x the steady peak remain."""
    from fydpad.texture.fit import fit_texture
    from fydpad.texture.scan_generator import generate_scan

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model, _ = fit_texture([generate_scan("sandpaper_p80", s, 3.0, seed=1)
                                for s in (10.0, 20.0, 30.0, 40.0)], order=200)
    rng = np.random.default_rng(0)
    v = np.repeat(rng.uniform(5.0, 45.0, 2000), 5)  # a new speed every 5 ms for 10 s
    y = synthesize(model, v, seed=1)
    assert np.isfinite(y).all()
    steady = synthesize(model, np.full(10_000, 40.0), seed=2)
    assert np.max(np.abs(y)) < 30 * np.max(np.abs(steady))
    hand = generate_scan("sandpaper_p80", 25.0, 10.0, seed=5).speed_mm_s
    assert np.max(np.abs(synthesize(model, hand, seed=1))) < 2 * np.max(np.abs(steady))
