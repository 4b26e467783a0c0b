"""The live inverse: minimum-phase FIR design, per-sample and block paths that agree,
and the offline FFT form (eqs. 2-4) on a chain whose TF is known exactly."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from fydpad.chain.compensate import compensate_offline, regularised_inverse
from fydpad.chain.estimate import TfEstimate
from fydpad.chain.excitation import band_noise
from fydpad.chain.inverse_filter import InverseFilter, fir_filter, min_phase_fir

RATE = 1000.0


def resonance(f0_hz: float = 200.0, zeta: float = 0.12):
    """A known chain: base-excited resonance, discretised (bilinear), as (b, a)."""
    w0 = 2 * np.pi * f0_hz
    return signal.bilinear([2 * zeta * w0, w0 * w0], [1, 2 * zeta * w0, w0 * w0], RATE)


def test_tick_and_block_agree_with_state_carried():
    rng = np.random.default_rng(0)
    taps = rng.normal(size=37)
    x = rng.normal(size=1000)
    live = InverseFilter(taps)
    y_tick = np.array([live.tick(v) for v in x])
    y1, z = fir_filter(taps, x[:333])
    y2, z = fir_filter(taps, x[333:], z)
    np.testing.assert_allclose(np.concatenate([y1, y2]), y_tick, atol=1e-12)
    np.testing.assert_allclose(live.state(), z, atol=0)
    np.testing.assert_allclose(y_tick, signal.lfilter(taps, 1.0, x), atol=1e-12)


def test_set_state_resumes_a_block():
    rng = np.random.default_rng(1)
    taps = rng.normal(size=16)
    x = rng.normal(size=300)
    _, z = fir_filter(taps, x[:100])
    live = InverseFilter(taps)
    live.set_state(z)
    y_tick = np.array([live.tick(v) for v in x[100:]])
    np.testing.assert_allclose(y_tick, fir_filter(taps, x[100:], z)[0], atol=1e-12)
    with pytest.raises(ValueError, match="zi must have shape"):
        live.set_state(np.zeros(3))


def test_min_phase_fir_inverts_a_resonance():
    b, a = resonance()
    # Up to 450 Hz, held above (the bilinear map puts a zero of the chain at Nyquist).
    f = np.linspace(0, 450, 461)
    _, h = signal.freqz(b, a, worN=f, fs=RATE)
    taps = min_phase_fir(f, 1.0 / np.abs(h), RATE, ntaps=128)
    _, g = signal.freqz(taps, 1.0, worN=f, fs=RATE)
    band = (f >= 10) & (f <= 400)
    err_db = 20 * np.log10(np.abs(g[band] * h[band]))
    assert np.max(np.abs(err_db)) < 0.5
    assert np.all(np.abs(np.roots(taps)) < 1.0)  # minimum phase: zeros inside


def test_offline_compensation_reproduces_the_target():
    # The chain's exact TF on the FFT grid: W = Z TF = FIV (eq. 5).
    b, a = resonance()
    n = 8192
    f = np.fft.rfftfreq(n, 1 / RATE)
    _, h = signal.freqz(b, a, worN=f, fs=RATE)
    est = TfEstimate(f, h, np.ones_like(f))
    target = band_noise(n, RATE, (20.0, 400.0), 1.0, seed=2)
    z = compensate_offline(target, RATE, est, (10.0, 450.0), eps=1e-4)
    w = np.fft.irfft(np.fft.rfft(z) * h, n)  # the chain, applied in the same periodic form
    assert np.max(np.abs(w - target)) < 1e-3 * np.max(np.abs(target))


def test_regularisation_caps_the_boost_where_tf_is_small():
    f = np.linspace(0, 500, 257)
    tf = np.ones(257, complex)
    tf[100:110] = 1e-4  # a deep notch: 1/TF would be +80 dB
    coh = np.ones(257)
    coh[200:] = 0.2  # poorly measured above 390 Hz
    tf[200:] = 1e-6
    inv = regularised_inverse(TfEstimate(f, tf, coh), (10.0, 450.0), eps=0.05)
    assert np.max(np.abs(inv)) <= 1.0 / (2 * 0.05) + 1e-9
    # Above the coherent band: the last coherent bin's value, no boost.
    assert np.allclose(np.abs(inv[200:]), np.abs(inv[199]))


def test_the_documented_boost_cap_is_the_default_eps():
    # The cap 1 / (2 eps) over the typical gain, as the module and docs/chain.md state it.
    from pathlib import Path

    from fydpad.chain import compensate

    cap_db = 20 * np.log10(1 / (2 * compensate.EPS))
    text = f"``EPS`` = {compensate.EPS:g}: at most +{cap_db:.0f} dB"
    assert text in " ".join(compensate.__doc__.split())
    doc = " ".join((Path(__file__).parents[2] / "docs" / "chain.md").read_text().split())
    assert f"eps = {compensate.EPS:g}" in doc and f"= +{cap_db:.0f} dB" in doc
    f = np.linspace(0, 500, 257)
    tf = np.ones(257, complex)
    tf[100:110] = compensate.EPS  # |TF| = eps ref: where the regularised inverse peaks
    inv = regularised_inverse(TfEstimate(f, tf, np.ones(257)), (10.0, 450.0))
    assert 20 * np.log10(np.max(np.abs(inv))) == pytest.approx(cap_db, abs=0.01)
