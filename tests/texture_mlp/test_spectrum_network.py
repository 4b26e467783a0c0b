"""The spectrum network (beyond thesis 003): valid LSFs, learning, files, LPC comparison."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.texture.families.mlp.lsf import (
    SpectrumNet,
    SpectrumTrainConfig,
    WindowFits,
    load_spectrum_net,
    net_to_json,
    save_spectrum_net,
    train_spectrum,
)
from fydpad.texture.lpc import is_stable
from fydpad.texture.lsf import lsf_is_valid, lsf_to_poly, poly_to_lsf

FS = 1000.0


def _random_net(rng, p=12, hdim=8, scale=1.0):
    return SpectrumNet(rng.normal(0, scale, (hdim, 2)), rng.normal(0, scale, hdim),
                       rng.normal(0, 30 * scale, (p + 1, hdim)), rng.normal(0, 30 * scale, p + 1),
                       rng.normal(0, scale, hdim), 0.0, np.zeros(2), np.ones(2))


def test_any_weights_give_strictly_ordered_lsfs_in_0_pi():
    """The construction's guarantee (sorted LSFs: a stable 1/A in exact arithmetic). In
    floating point, LSFs crowded within 1e-3 rad lose it at order 200 (lsf_to_poly);
    trained nets stay far from that (their filters are checked below)."""
    rng = np.random.default_rng(0)
    for k in range(5):
        net = _random_net(rng, scale=10.0 ** (k - 2))
        lsf, s2 = net.predict(rng.uniform(-1e3, 1e3, 200), rng.uniform(-50, 50, 200))
        assert all(lsf_is_valid(row) for row in lsf) and np.all(s2 > 0)
        assert np.min(np.diff(lsf, axis=1)) >= 0.99e-4


def _truth(v, f):
    """A known texture law: resonances at 3 v Hz and 200 Hz; variance grows with v and f."""
    polys = []
    for vi in np.atleast_1d(v):
        a = np.array([1.0])
        for f0 in (3.0 * vi, 200.0):
            w = 2 * np.pi * f0 / FS
            a = np.convolve(a, [1.0, -2 * 0.95 * np.cos(w), 0.95**2])
        polys.append(a)
    lsf = np.vstack([poly_to_lsf(a) for a in polys])
    return lsf, np.log(0.01 * np.atleast_1d(v)) + 0.5 * np.atleast_1d(f)


@pytest.fixture(scope="module")
def law():
    rng = np.random.default_rng(1)
    v = rng.uniform(10, 40, 80)
    f = rng.uniform(0.5, 1.5, 80)
    lsf, lv = _truth(v, f)
    fits = WindowFits(v, f, lsf + rng.normal(0, 0.002, lsf.shape), lv + rng.normal(0, 0.02, 80))
    net, hist = train_spectrum(fits, SpectrumTrainConfig(iterations=2000))
    return v, net, hist


def test_training_learns_a_known_speed_and_force_law(law):
    v, net, hist = law
    assert hist[-1] < 0.05 * hist[0]
    vt, ft = np.array([12.5, 23.3, 31.7, 38.0]), np.array([0.6, 1.4, 1.0, 0.8])
    want_lsf, want_lv = _truth(vt, ft)
    got_lsf, got_s2 = net.predict(vt, ft)
    # resonance at 3 v Hz: 38-114 Hz; LSFs within 0.01 rad (1.6 Hz) of the law's
    assert np.max(np.abs(got_lsf - want_lsf)) < 0.01
    np.testing.assert_allclose(np.log(got_s2), want_lv, atol=0.05)  # force is used: 0.5/N
    tm = net.texture_model(step_mm_s=2.5)
    assert tm.speeds_mm_s[0] == pytest.approx(v.min()) and tm.speeds_mm_s[-1] <= v.max() + 2.5
    assert all(is_stable(tm.poly(i)) for i in range(tm.speeds_mm_s.size))


def test_training_is_deterministic_for_a_seed():
    rng = np.random.default_rng(2)
    v = rng.uniform(10, 40, 30)
    lsf, lv = _truth(v, np.ones(30))
    fits = WindowFits(v, np.ones(30), lsf, lv)
    a, _ = train_spectrum(fits, SpectrumTrainConfig(iterations=50, seed=4))
    b, _ = train_spectrum(fits, SpectrumTrainConfig(iterations=50, seed=4))
    c, _ = train_spectrum(fits, SpectrumTrainConfig(iterations=50, seed=5))
    np.testing.assert_array_equal(a.w2, b.w2)
    assert not np.array_equal(a.w2, c.w2)


def test_model_file_round_trip_registry_and_bad_files(law, tmp_path):
    from fydpad.texture.families import constant_stroke, load_family

    net = law[1]
    p = save_spectrum_net(net, tmp_path / "n.json")
    back = load_spectrum_net(p)
    np.testing.assert_array_equal(back.w2, net.w2)
    fam = load_family(f"mlp_lsf:{p}")
    assert fam.kind == "mlp_lsf"
    y = fam.render(constant_stroke(20.0, 1.0, FS))
    assert y.size == 1000 and np.isfinite(y).all() and np.std(y) > 0
    # Through eq. 5 it renders the law's spectrum at 20 mm/s, 1 N (resonances at 60 and
    # 200 Hz): Welch estimate against sigma^2 / |A|^2 of the law itself.
    import scipy.signal as ss

    fam.seed = 7
    fam.reset()
    f, pxx = ss.welch(fam.render(constant_stroke(20.0, 16.0, FS)), FS, nperseg=256)
    lsf, lv = _truth(np.array([20.0]), np.array([1.0]))
    a = lsf_to_poly(lsf[0])
    _, h = ss.freqz([1.0], a, worN=f, fs=FS)
    want = 2.0 / FS * np.exp(lv[0]) * np.abs(h) ** 2
    band = (f >= 20) & (f <= 480)
    d = 10 * np.log10(pxx[band] / want[band])
    # measured 0.37 dB; the law at 22 mm/s instead: 1.25 dB
    assert np.sqrt(np.mean(d**2)) < 0.8, np.sqrt(np.mean(d**2))
    data = net_to_json(net)
    data["weights"]["w2"] = data["weights"]["w2"][:-1]
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"bad\.json: weights: key 'w2' has shape"):
        load_spectrum_net(tmp_path / "bad.json")
    data = net_to_json(net)
    data["speed_range_mm_s"] = [40, 10]
    (tmp_path / "range.json").write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"range\.json: key 'speed_range_mm_s'"):
        load_spectrum_net(tmp_path / "range.json")


@pytest.fixture(scope="module")
def r1_between():
    from benchmarks.bench_mlp_accuracy import spectrum_vs_lpc

    return spectrum_vs_lpc("R1", held_speeds=(25.0,))[0]


def test_between_modelled_speeds_the_network_beats_lsf_interpolation(r1_between):
    """R1 at 25 mm/s, held-out stroke: measured corr 0.838 vs 0.759 (order-100 network
    against the order-200 LPC family with LSF interpolation; 0.898 vs 0.683 before
    session 14's hand, whose strokes wander 9 % RMS)."""
    r = r1_between
    assert r["corr_net"] > r["corr_lpc"] + 0.05, r


@pytest.mark.xfail(strict=True, reason="measured R1 at 25 mm/s: LSD 2.30 dB for the network, "
                   "2.31 for LSF interpolation, a tie (2.23 against 2.85 before session 14's "
                   "hand, whose strokes wander 9 % RMS) (docs/texture_mlp.md)")
def test_between_modelled_speeds_the_networks_lsd_beats_lsf_interpolation(r1_between):
    r = r1_between
    assert r["lsd_net"] < r["lsd_lpc"] - 0.1, r


@pytest.mark.xfail(strict=True, reason="measured R1 at 25 mm/s: corr 0.838 (< 0.95), LSD "
                   "2.30 dB against a ceiling of 1.52 dB (> +0.25; 2.23 against 0.49 before "
                   "session 14's hand): windows of a hand's stroke cover 25 mm/s too thinly")
def test_network_meets_the_issue_7_targets_between_speeds(r1_between):
    r = r1_between
    assert r["corr_net"] >= 0.95 and r["lsd_net"] <= r["lsd_ceiling"] + 0.25, r
