"""LPC estimation, stability, LSF/reflection conversions and stable interpolation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss
from hypothesis import given, settings
from hypothesis import strategies as st

from fydpad.texture.interpolation import SpeedInterpolator, build_table
from fydpad.texture.lpc import (
    h_from_poly,
    is_stable,
    levinson,
    lpc_autocorrelation,
    lpc_burg,
    max_pole_radius,
    poly_to_reflection,
    reflection_to_poly,
)
from fydpad.texture.lsf import lsf_is_valid, lsf_to_poly, poly_to_lsf
from fydpad.texture.model_file import TextureModel
from fydpad.texture.speed_warp import NFFT, ar_from_log_psd, log_psd

TRUE_A = np.array([1.0, -1.6, 1.5, -0.7, 0.2])


@pytest.fixture(scope="module")
def ar_signal() -> np.ndarray:
    rng = np.random.default_rng(0)
    return ss.lfilter([1.0], TRUE_A, rng.normal(0, 0.1, 200_000))


def test_levinson_and_burg_recover_known_ar(ar_signal):
    for a, s2 in (lpc_autocorrelation([ar_signal], 4), lpc_burg(ar_signal, 4)):
        np.testing.assert_allclose(a, TRUE_A, atol=0.01)
        assert s2 == pytest.approx(0.01, rel=0.02)


def test_pooled_segments_equal_one_long_segment_closely(ar_signal):
    a1, _ = lpc_autocorrelation([ar_signal], 4)
    a2, _ = lpc_autocorrelation(np.array_split(ar_signal, 10), 4)
    np.testing.assert_allclose(a1, a2, atol=5e-3)


def test_order_200_fit_is_stable(ar_signal):
    a, _ = lpc_autocorrelation([ar_signal[:10_000]], 200)
    assert is_stable(a) and max_pole_radius(a) < 1.0


def test_stability_check_detects_unstable():
    assert not is_stable([1.0, -2.1, 1.1])  # a pole at 1.1
    assert is_stable([1.0, -0.5])
    k = poly_to_reflection(TRUE_A)
    np.testing.assert_allclose(reflection_to_poly(k), TRUE_A, atol=1e-12)
    _, _, k2 = levinson(np.array([1.0, 0.5, 0.2]), 2)
    assert np.all(np.abs(k2) < 1)


def test_lsf_round_trip_order_200(ar_signal):
    a, _ = lpc_autocorrelation([ar_signal[:20_000]], 200)
    lsf = poly_to_lsf(a)
    assert lsf.size == 200 and lsf_is_valid(lsf)
    np.testing.assert_allclose(lsf_to_poly(lsf), a, atol=1e-9)


def _resonators(angles, r: float = 0.98) -> np.ndarray:
    a = np.array([1.0])
    for t in angles:
        a = np.convolve(a, [1.0, -2.0 * r * np.cos(t), r * r])
    return a


def _random_stable(rng: np.random.Generator, order: int) -> np.ndarray:
    """A fitted model of a random texture-like signal: a few sharp resonances (radius up
    to 0.995, like a tool mode or a grating line) over a noise floor, fitted at ``order``."""
    a = _resonators(rng.uniform(0.05, np.pi - 0.05, rng.integers(1, 6)), rng.uniform(0.9, 0.995))
    x = ss.lfilter([1.0], a, rng.standard_normal(4000))
    x += 1e-3 * np.std(x) * rng.standard_normal(x.size)
    return lpc_autocorrelation([x], order)[0]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), w=st.floats(0.0, 1.0), order=st.sampled_from([8, 40, 200]))
def test_every_lsf_and_reflection_interpolation_is_stable(seed, w, order):
    rng = np.random.default_rng(seed)
    a0, a1 = _random_stable(rng, order), _random_stable(rng, order)
    model = TextureModel("x", 1000.0, np.array([10.0, 20.0]),
                         np.vstack([h_from_poly(a0), h_from_poly(a1)]), np.array([1e-3, 2e-3]))
    for method in ("lsf", "reflection"):
        a, s2 = SpeedInterpolator(model, method)(10.0 + 10.0 * w)
        assert is_stable(a), method
        assert 1e-3 <= s2 <= 2e-3


def test_paper_linear_interpolation_can_be_unstable_and_lsf_not():
    # Two stable pairs of resonators whose coefficient average is unstable.
    a0, a1 = _resonators([1.9, 0.9]), _resonators([0.2, 0.1])
    assert is_stable(a0) and is_stable(a1)
    model = TextureModel("x", 1000.0, np.array([10.0, 20.0]),
                         np.vstack([h_from_poly(a0), h_from_poly(a1)]), np.array([1.0, 1.0]))
    lin = build_table(model, "linear", 0.5)
    lsf = build_table(model, "lsf", 0.5)
    assert lsf.stable.all()
    assert not lin.stable.all()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), v=st.floats(10.0, 30.0), order=st.sampled_from([8, 40, 200]))
def test_every_stretch_interpolation_is_stable(seed, v, order):
    """The default: warped spectra mixed and refitted by Levinson; stable at any speed."""
    rng = np.random.default_rng(seed)
    polys = [_random_stable(rng, order) for _ in range(3)]
    model = TextureModel("x", 1000.0, np.array([10.0, 20.0, 30.0]),
                         np.vstack([h_from_poly(a) for a in polys]),
                         10.0 ** rng.uniform(-4, 0, 3))
    a, s2 = SpeedInterpolator(model, "stretch")(v)
    assert a.size == order + 1 and is_stable(a)
    assert np.isfinite(s2) and s2 > 0


# A surface whose vibration is purely spatial: power spectrum v^3 S(f / v) (eq. of
# speed_warp with beta = 1) over a sensor floor, S a band of wavenumbers 1-6 /mm with
# steep edges, optionally a comb of period 0.5 mm. Models are order-100 fits to the
# exact spectrum at 10, 20, 30, 40 mm/s; the truth between them is the same fit at v.
_F_HZ = np.arange(NFFT // 2 + 1) * 1000.0 / NFFT


def _spatial_log_psd(v: float, comb_mm: float = 0.0) -> np.ndarray:
    k = _F_HZ / v
    s = k**4 / (1 + k**4) / (1 + (k / 6.0) ** 8)
    if comb_mm:
        s = s * (0.05 + np.cos(np.pi * k * comb_mm) ** 40)
    return np.log(v**3 * s + 1e-6)


@pytest.mark.parametrize("comb_mm", [0.0, 0.5])
def test_stretch_follows_a_spatial_spectrum_between_models(comb_mm):
    fits = [ar_from_log_psd(_spatial_log_psd(v, comb_mm), 100) for v in (10.0, 20.0, 30.0, 40.0)]
    model = TextureModel("spatial", 1000.0, np.array([10.0, 20.0, 30.0, 40.0]),
                         np.vstack([h_from_poly(a) for a, _ in fits]),
                         np.array([e for _, e in fits]))
    band = (_F_HZ >= 20) & (_F_HZ <= 480)

    def worst_lsd(interp) -> float:
        out = []
        for v in (12.5, 15.0, 25.0, 35.0):
            a, s2 = interp(v)
            ta, ts = ar_from_log_psd(_spatial_log_psd(v, comb_mm), 100)
            d = 10 / np.log(10) * (log_psd(a, s2)[0] - log_psd(ta, ts)[0])[band]
            out.append(np.sqrt(np.mean(d * d)))
        return max(out)

    # No hold: the fits are of exact spectra at exactly their speed, nothing to hold.
    stretch = SpeedInterpolator(model, "stretch", hold_mm_s=0.0)
    assert stretch._warp.beta >= 0.7  # recognised as (mostly) spatial
    mine, lsf = worst_lsd(stretch), worst_lsd(SpeedInterpolator(model, "lsf"))
    assert mine < 2.0, mine  # measured 0.8 (band), 1.7 (comb)
    assert mine < 0.5 * lsf, (mine, lsf)  # LSF: 3.0 and 6.2 dB


def test_stretch_keeps_a_temporal_spectrum_in_place():
    """A resonance that does not move with speed (a tool mode): beta ~ 0, level follows."""
    a0 = _resonators([0.9 * np.pi / 2.5], 0.97)
    model = TextureModel("tool", 1000.0, np.array([10.0, 20.0, 30.0]),
                         np.vstack([h_from_poly(a0)] * 3), np.array([1e-3, 4e-3, 9e-3]))
    it = SpeedInterpolator(model, "stretch", hold_mm_s=0.0)
    assert it._warp.beta == pytest.approx(0.0)
    assert it._warp.gamma == pytest.approx(2.0, abs=0.05)
    a, s2 = it(15.0)
    np.testing.assert_allclose(log_psd(a, s2)[0], log_psd(a0, 1e-3 * 1.5**2)[0], atol=0.05)


def test_normalise_speed_turns_a_spatial_tone_scanned_at_a_wandering_speed_into_one_line():
    """Ground truth: a surface sin(2 pi x / lambda) scanned at 20 mm/s +-20 % sounds at
    v / lambda (smeared over 8-12 Hz x harmonics); moved to 25 mm/s in space (beta = 1)
    it is one line at 25 / lambda."""
    from fydpad.texture.speed_warp import normalise_speed

    fs, lam = 1000.0, 0.2  # mm: 100-150 Hz
    t = np.arange(8000) / fs
    v = 20.0 * (1 + 0.2 * np.sin(2 * np.pi * 0.5 * t))
    x_mm = np.cumsum(v) / fs
    y, top = normalise_speed(np.sin(2 * np.pi * x_mm / lam), v, 25.0, 1.0, 0.0)
    f = np.fft.rfftfreq(y.size, 1 / fs)
    p = np.abs(np.fft.rfft(y * np.hanning(y.size))) ** 2
    raw = np.abs(np.fft.rfft(np.sin(2 * np.pi * x_mm / lam) * np.hanning(t.size))) ** 2
    assert abs(f[np.argmax(p)] - 25.0 / lam) < 0.5
    near = np.abs(f - 125.0) <= 2.0
    assert p[near].sum() / p.sum() > 0.95  # one line
    assert raw[np.abs(np.fft.rfftfreq(t.size, 1 / fs) - 100.0) <= 2.0].sum() / raw.sum() < 0.3
    assert top == pytest.approx(25.0 / 24.0, rel=0.01)  # data up to fs/2 * v0 / v_max
