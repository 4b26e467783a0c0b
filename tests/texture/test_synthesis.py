"""Eq. 5 synthesis: per-sample and block paths, silence, fade, clamp, continuity."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.lpc.analysis import ar_psd, h_from_poly, lpc_autocorrelation
from fydpad.texture.lpc.fit import fit_paper, fit_texture
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.synthesis import (
    WARP_SLACK_MM_S,
    TextureRenderer,
    synthesize,
    table_position,
)
from tests.texture.test_fir_warp import responses_along


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


@pytest.mark.parametrize("structure", ["fir", "direct"])  # FIR and eq. 5 direct form
def test_tick_and_block_give_the_same_samples(model, structure):
    # A ramp, a hold, a hand's back-and-forth (each table entry visited in several
    # separate runs) and jumps every 5 ms (the block path groups samples by entry).
    t = np.arange(1500) / 1000.0
    jumps = np.repeat(np.random.default_rng(0).uniform(5.0, 45.0, 2000), 5)
    v = np.concatenate([np.linspace(0, 45, 1500), np.full(1000, 25.0),
                        25.0 + 15.0 * np.sin(2 * np.pi * 2.0 * t), jumps])
    n = v.size
    c = np.ones(n, bool)
    c[1700:1800] = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r1 = TextureRenderer(model, seed=5, drive_filter=True, structure=structure)
        r2 = TextureRenderer(model, seed=5, drive_filter=True, structure=structure)
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
        # Within the fastest model's fit tolerance (40 + 5 mm/s) its data cover the speed.
        r.block(44.0, True, 100)
        r.tick(44.9, True)
        assert not r.clamped and not caught
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


@pytest.fixture(scope="module")
def sandpaper() -> TextureModel:
    """A fitted texture whose power spans ~45 dB over 10-40 mm/s (a band edge crossing the
    tool mode): the paper's per-speed fits on a 1 mm/s grid, rendered below by either
    structure (the calibrated spectrum's table changes faster with speed: its hand's-
    stroke leak into the weak 320-420 Hz band is +3.7 dB, docs/texture.md)."""
    return fit_paper([generate_scan("sandpaper_p80", s, 3.0, seed=1)
                      for s in (10.0, 20.0, 30.0, 40.0)], order=200)


def _synth(model: TextureModel, v: np.ndarray, seed: int, structure: str) -> np.ndarray:
    r = TextureRenderer(model, seed=seed, ramp_s=1e-6, structure=structure)
    r.warmup(float(v[0]))
    return r.block(v, True)


@pytest.mark.parametrize("structure", ["fir", "direct"])
def test_switching_at_the_speed_rate_stays_bounded(sandpaper, structure):
    """The speed jumping anywhere every 5 ms: the switched filter must not run away (a
    stable filter each is not enough; direct form without the history cap reaches
    1e60). Direct form: transients of ~10x the steady peak remain."""
    rng = np.random.default_rng(0)
    v = np.repeat(rng.uniform(5.0, 45.0, 2000), 5)  # a new speed every 5 ms for 10 s
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        y = _synth(sandpaper, v, 1, structure)
        steady = _synth(sandpaper, np.full(10_000, 40.0), 2, structure)
        hand = generate_scan("sandpaper_p80", 25.0, 10.0, seed=5).speed_mm_s
        y_hand = _synth(sandpaper, hand, 1, structure)
    assert np.isfinite(y).all()
    assert np.max(np.abs(y)) < 30 * np.max(np.abs(steady))
    assert np.max(np.abs(y_hand)) < 2 * np.max(np.abs(steady))


def _fir_at(r: TextureRenderer, v: np.ndarray, warped: bool = False) -> np.ndarray:
    """The FIR each sample used: linear between the two table entries around its speed
    (``warped``: each lag's at its own speed, lag_speeds; the history before ``v`` held at
    v[0], as after a warm-up)."""
    t = r.table
    if warped:
        return responses_along(r.fir, float(t.speeds_mm_s[0]), t.step_mm_s, v)
    i, w = table_position(v, float(t.speeds_mm_s[0]), t.step_mm_s, r.fir.shape[0])
    w = w[:, None]
    return (1 - w) * r.fir[i] + w * r.fir[i + 1]


@pytest.mark.parametrize("seed", [0, 1])
def test_fir_output_power_is_the_filters_at_every_sample(sandpaper, seed):
    """FIR structure: y(k) / ||g_v(k)|| is unit-variance noise whatever the switching
    (measured mean square 0.97-1.02 over 10 s with a jump every 5 ms)."""
    rng = np.random.default_rng(seed)
    v = np.repeat(rng.uniform(5.0, 45.0, 2000), 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = TextureRenderer(sandpaper, seed=seed, ramp_s=1e-6, structure="fir")
        r.warmup(float(v[0]))
        y = r.block(v, True)
    ratio = np.mean(y**2 / np.sum(_fir_at(r, v, warped=True) ** 2, axis=1))
    assert abs(ratio - 1.0) < 0.1, ratio


def _expected_welch(g: np.ndarray, nper: int = 250, fs: float = 1000.0) -> np.ndarray:
    """E[Welch PSD] (Hann, nper) of the FIR process averaged over the rows of g."""
    w = ss.get_window("hann", nper)
    cw = np.correlate(w, w, "full")[nper - 1:] / np.sum(w * w)
    nfft = 1 << int(np.ceil(np.log2(2 * g.shape[1])))  # no circular aliasing of lags
    r = np.fft.irfft(np.mean(np.abs(np.fft.rfft(g, nfft, axis=1)) ** 2, axis=0), nfft)
    r = r[:nper] * cw
    return 2 * np.fft.rfft(np.concatenate([r, [0.0], r[:0:-1]])).real[::2] / fs


@pytest.fixture(scope="module")
def sandpaper_calibrated() -> TextureModel:
    """The same scans fitted by default (the calibrated spectrum)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = fit_texture([generate_scan("sandpaper_p80", s, 3.0, seed=1)
                             for s in (10.0, 20.0, 30.0, 40.0)], order=200)
    return model


@pytest.mark.xfail(strict=True, reason="calibrated fit along a hand's stroke: LSD 2.24 dB "
                   "(measured)")
def test_fir_spectrum_of_the_default_fit_along_a_hands_stroke(sandpaper_calibrated):
    test_fir_spectrum_along_a_hands_stroke_has_no_switching_leak(sandpaper_calibrated)


def test_fir_spectrum_along_a_hands_stroke_has_no_switching_leak(sandpaper):
    """Along a hand's stroke (20-29 mm/s) the spectrum is the filters' average: no leak
    of the strong low band into the weak top one. Measured LSD 0.9-1.2 dB (the Welch
    estimate alone scatters ~0.55 dB); a stepwise table FIR gives 11 dB (+27 dB at
    440-480 Hz), which is why g is interpolated between table entries."""
    hand = generate_scan("sandpaper_p80", 25.0, 10.0, seed=6).speed_mm_s
    r = TextureRenderer(sandpaper, seed=1, ramp_s=1e-6, structure="fir")
    r.warmup(float(hand[0]))
    y = r.block(hand, True)[500:-500]  # the steady part, no ramps
    f, p = ss.welch(y, 1000.0, nperseg=250)
    expected = _expected_welch(_fir_at(r, hand[500:-500:5]))  # speed is smooth
    sel = (f >= 20) & (f <= 480)
    d = 10 * np.log10(p[sel] / expected[sel])
    assert np.sqrt(np.mean(d * d)) < 2.0


def _line_model(r: float = 0.99, period_mm: float = 2.5) -> TextureModel:
    """A purely spatial line, f = v / period, over a faint white floor: the narrow,
    gliding resonance of a ribbed surface (corduroy) as an all-pole process, fitted at
    every table speed (0.25 mm/s) on the same noise, so the nearest model glides."""
    e = np.random.default_rng(1).standard_normal((2, 20000))
    speeds = np.arange(10.0, 40.01, 0.25)
    hs, s2 = [], []
    for v in speeds:
        w = 2 * np.pi * v / period_mm / 1000.0
        x = ss.lfilter([1.0], [1.0, -2 * r * np.cos(w), r * r], e[0])
        a, s = lpc_autocorrelation([x / x.std() + 0.001 * e[1]], 16)
        hs.append(h_from_poly(a))
        s2.append(s)
    return TextureModel("line", 1000.0, speeds, np.vstack(hs), np.array(s2))


def test_fir_lags_follow_the_speed_they_were_made_at():
    """Fast starts and stops (5 -> 30 mm/s in 50 ms, held 0.25 s, back, 30 times) under a
    narrow line at v / 2.5 mm (12 Hz at most): no instant's filter puts power at
    20-100 Hz beyond its floor, so the output there must be the filters' average. The
    plain FIR (the filter of now applied to noise up to 0.5 s old) sprays the line there:
    measured +5.0-5.4 dB (noise seeds 1-3); each lag at the mean speed over it
    (lag_speeds, 512 lags): +1.2-1.5 dB."""
    model = _line_model()
    cycle = np.concatenate([np.linspace(5, 30, 50), np.full(250, 30.0),
                            np.linspace(30, 5, 50), np.full(250, 5.0)])
    v = np.tile(cycle, 30)
    excess = {}
    for slack in (float("inf"), WARP_SLACK_MM_S):
        r = TextureRenderer(model, seed=1, ramp_s=1e-6, structure="fir")
        r.warp_slack_mm_s = slack
        r.warmup(5.0)
        f, p = ss.welch(r.block(v, True), 1000.0, nperseg=250)
        expected = _expected_welch(_fir_at(r, v[::5]))
        sel = (f >= 20) & (f <= 100)
        excess[slack] = float(np.mean(10 * np.log10(p[sel] / expected[sel])))
    assert excess[float("inf")] > 3.0, excess  # the scenario shows the leak
    assert excess[WARP_SLACK_MM_S] < 1.5, excess


def test_tick_and_block_agree_with_a_response_longer_than_the_warped_lags(sandpaper):
    """The same as the test above on sandpaper_p80's per-speed table (responses of ~4000 taps:
    512 warped lags and a plain tail), with starts and stops, a lost track (NaN) mid-
    stroke, 0.6 s at 1e306 mm/s (a mean of 512 such speeds overflowed: IndexError), and
    block calls of 1 and 0 samples between."""
    hand = generate_scan("sandpaper_p80", 25.0, 3.0, seed=5).speed_mm_s
    v = np.concatenate([hand, np.linspace(25, 0, 200), np.zeros(100), np.linspace(0, 40, 150),
                        [np.nan, np.nan], np.full(300, 40.0), np.full(600, 1e306),
                        np.full(200, 30.0)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r1 = TextureRenderer(sandpaper, seed=3, structure="fir")
        r2 = TextureRenderer(sandpaper, seed=3, structure="fir")
        assert r1.fir.shape[1] > 512
        cut = 1700
        yb = np.concatenate([r1.block(v[:cut]), r1.block(v[cut:cut + 1]),
                             r1.block(v[cut + 1:cut + 1], n=0), r1.block(v[cut + 1:])])
        yt = np.array([r2.tick(float(s)) for s in v])
    assert np.isfinite(yt).all()
    np.testing.assert_allclose(yb, yt, atol=1e-12)


@pytest.mark.parametrize("structure", ["fir", "direct"])
def test_lpc_family_after_reset_renders_as_a_fresh_one(model, structure, monkeypatch):
    """LpcFamily keeps its renderer (a calibrated table is hundreds of all-pole fits): after
    ``reset()``, a new seed or a new drive filter it renders exactly what a new family with
    those parameters renders, the clamp warning included."""
    import fydpad.texture.lpc.family as lpc_family
    from fydpad.texture.family import FingerBlock

    class Renderer(TextureRenderer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **{**kwargs, "structure": structure})

    monkeypatch.setattr(lpc_family, "TextureRenderer", Renderer)
    t = np.arange(3000) / 1000
    speed = 25 + 30 * np.sin(2 * np.pi * 0.5 * t)  # above 45 mm/s: clamped, warned
    stroke = FingerBlock(1000.0, t, np.arange(3000) % 700 < 500, np.cumsum(speed) / 1000,
                         np.zeros(3000), speed, np.ones(3000))

    def fresh(**params):
        fam = lpc_family.LpcFamily(model)
        for name, value in params.items():
            fam.set_parameter(name, value)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            return fam.render(stroke), len(caught)

    used = lpc_family.LpcFamily(model)
    used.set_parameter("seed", 5)
    used.render(stroke)
    for change, params in ((lambda: used.reset(), {"seed": 5}),
                           (lambda: used.set_parameter("seed", 7), {"seed": 7}),
                           (lambda: used.set_parameter("drive_filter", True),
                            {"seed": 7, "drive_filter": True})):
        change()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            y = used.render(stroke)
        want, n_warned = fresh(**params)
        assert np.array_equal(y, want)
        assert len(caught) == n_warned == 1
