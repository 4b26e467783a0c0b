"""The two-part spectral model (fydpad/texture/lpc/spectrum.py) against ground truth.

Data: Gaussian noise shaped to a known S(f, v) = T(f) U(f/v) g(v) + N(f), so the right
answer at a speed the fit never saw is known exactly.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.lpc.analysis import is_stable
from fydpad.texture.lpc.fit import fit_texture
from fydpad.texture.lpc.interpolation import build_table
from fydpad.texture.lpc.model_file import load_model, model_to_json, parse_model, save_model
from fydpad.texture.lpc.spectrum import CalibratedSpectrum, TwoPartSpectrum, fit_two_part
from tests.texture.test_calibrated import fit_calibrated_by_cli

FS = 1000.0


def true_psd(f_hz, v_mm_s):
    """A spatial band at 4 /mm (80 Hz at 20 mm/s) seen through a fixed 200 Hz mode, plus a
    fixed floor."""
    tool = 1.0 / (1.0 + ((f_hz - 200.0) / 40.0) ** 2) + 0.05
    surface = 0.2 + 30.0 * np.exp(-(((f_hz / v_mm_s) - 4.0) / 0.4) ** 2)
    return tool * surface * (v_mm_s / 20.0) ** 2 + 1e-3


def shaped_noise(v_mm_s, seconds, rng, psd=true_psd):
    n = int(seconds * FS)
    f = np.fft.rfftfreq(n, 1 / FS)
    spec = (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) / np.sqrt(2)
    return np.fft.irfft(spec * np.sqrt(psd(f, v_mm_s) * n), n)


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(3)
    speeds = (10.0, 20.0, 30.0, 40.0)
    runs = [shaped_noise(v, 10.0, rng) for v in speeds]
    traces = [np.full(r.size, v) for r, v in zip(runs, speeds, strict=True)]
    return fit_two_part(runs, traces, FS, (5.0, 45.0))


def _db(x):
    return 10 * np.log10(x)


def _smooth(p):
    """Mean over 5 bins (10 Hz): the fit's per-bin scatter (0.75 dB rms at a fitted speed,
    the periodograms' own) averaged down, its bias kept."""
    return np.convolve(p, np.ones(5) / 5, mode="same")


def test_spectrum_between_fitted_speeds_matches_the_truth(fitted):
    """At 25 mm/s (no data there) the band sits at 100 Hz, between the fitted 80 and 120."""
    f = fitted.f_hz
    sel = (f >= 20) & (f <= 480)
    fit_db, truth_db = _db(_smooth(fitted.psd(25.0))[sel]), _db(_smooth(true_psd(f, 25.0))[sel])
    lsd = np.sqrt(np.mean((fit_db - truth_db) ** 2))
    # The neighbours mixed in log (what a cross-fade of the 20 and 30 mm/s spectra gives).
    mix_db = 0.5 * (_db(_smooth(true_psd(f, 20.0))) + _db(_smooth(true_psd(f, 30.0))))[sel]
    lsd_mix = np.sqrt(np.mean((mix_db - truth_db) ** 2))
    assert lsd < 1.0 and lsd < 0.5 * lsd_mix, (lsd, lsd_mix)
    band = (f >= 60) & (f <= 150)
    assert abs(f[band][np.argmax(fitted.psd(25.0)[band])] - 100.0) <= 4.0


def test_fixed_part_stays_put(fitted):
    """The 200 Hz mode is in T (it does not move with speed), the band is in U."""
    f = fitted.f_hz
    hi = (f >= 150) & (f <= 300)
    assert abs(f[hi][np.argmax(fitted.tool[hi])] - 200.0) <= 10.0
    assert abs(fitted.k_per_mm[np.argmax(fitted.surface)] - 4.0) <= 0.2


def test_mean_psd_is_the_weighted_mean_of_the_spectra(fitted):
    """mean_psd (the calibration's and the render's average over speeds, in one pass)
    against psd speed by speed, speeds beyond the fitted range included (held there)."""
    v = np.array([3.0, 10.0, 17.3, 25.0, 25.0, 44.9, 60.0])
    w = np.array([1.0, 2.0, 0.5, 3.0, 1.0, 4.0, 0.25])
    expected = sum(wi * fitted.psd(float(vi)) for vi, wi in zip(v, w, strict=True)) / w.sum()
    np.testing.assert_allclose(fitted.mean_psd(v, w), expected, rtol=1e-12)
    np.testing.assert_allclose(fitted.mean_psd(17.3), fitted.psd(17.3), rtol=1e-12)


def test_blas_limit_holds_in_the_main_thread_and_no_thread_leaves_it_changed():
    """one_blas_thread holds BLAS to one thread in the main thread and restores it, nested
    too; fits in other threads, overlapping in time, leave it alone (a save-and-restore
    per block from several threads left it at one thread for good)."""
    import threading
    import time

    from threadpoolctl import threadpool_info

    from fydpad.texture.lpc.spectrum import one_blas_thread

    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    before = blas_threads()
    if not before or min(before) < 2:
        # A limit left behind would not show (one core, or OPENBLAS_NUM_THREADS=1); setting
        # two threads first does not help: the main thread's own setting then hides it.
        pytest.skip(f"BLAS runs on one thread here already: {before}")
    with one_blas_thread():
        inside = blas_threads()
        with one_blas_thread():
            pass
        assert blas_threads() == inside
    assert inside == [1] * len(before)
    assert blas_threads() == before

    def fit(hold_s):
        with one_blas_thread():
            time.sleep(hold_s)

    first = threading.Thread(target=fit, args=(0.15,))
    second = threading.Thread(target=fit, args=(0.3,))
    first.start()
    time.sleep(0.05)
    second.start()  # enters while the first is inside, leaves after it
    first.join(5.0)
    second.join(5.0)
    assert blas_threads() == before


def test_levels_of_several_functions_are_each_ones_own():
    """_node_levels on a (knots, 2) array (the fit updates log g and log n together)
    gives each column what it gives alone, beyond the end knots too (bounded slopes)."""
    from fydpad.texture.lpc.spectrum import _hats, _node_levels

    log_v = np.log(np.arange(4.0, 46.0))
    log_knots = np.log(np.array([10.0, 20.0, 30.0]))
    phi = _hats(log_v, log_knots, clamp=False)
    levels = np.array([[0.0, 1.0], [3.0, -2.0], [2.5, 40.0]])  # 40: a slope to bound
    both = _node_levels(levels, log_v, log_knots, phi)
    for j in range(2):
        np.testing.assert_allclose(both[:, j], _node_levels(levels[:, j], log_v, log_knots,
                                                            phi), rtol=1e-14)


def test_all_pole_fit_of_the_spectrum_is_stable_and_close(fitted):
    # The render's all-pole fit, of the base alone (a zero correction).
    a, s2 = CalibratedSpectrum(fitted, np.array([25.0]), np.zeros((1, fitted.f_hz.size))).ar(
        25.0, 60, FS)
    assert is_stable(a)
    f = fitted.f_hz
    model = s2 / np.abs(np.exp(-2j * np.pi * np.outer(f / FS, np.arange(a.size))) @ a) ** 2
    sel = (f >= 20) & (f <= 480)
    # ar() renders S averaged over v +- 1 mm/s (see its docstring): compare with that.
    truth = np.mean([true_psd(f, v) for v in np.linspace(24.0, 26.0, 5)], axis=0)
    assert np.sqrt(np.mean((_db(model[sel]) - _db(truth[sel])) ** 2)) < 1.5


@pytest.fixture(scope="module")
def scan_model():
    """fit_texture (the calibrated form on its two-part base) on R1."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scans = [generate_scan("R1", v, 4.0, seed=1) for v in (10.0, 20.0, 30.0)]
        return fit_texture(scans, speeds_mm_s=(10.0, 20.0, 30.0), order=60)


def test_fit_texture_stores_the_spectrum_and_every_table_filter_is_stable(scan_model):
    assert scan_model.two_part is not None
    assert scan_model.provenance["spectral_model"] == "free-form"
    table = build_table(scan_model, step_mm_s=1.0)
    assert table.stable.all()
    # At a fitted speed the stored h is the table's filter (one model, two views).
    k = table.index(20.0)
    assert np.allclose(table.h[k], scan_model.h[1])


def test_model_file_round_trip(scan_model, tmp_path):
    back = load_model(save_model(scan_model, tmp_path / "m.json"))
    a = TwoPartSpectrum.from_json(back.two_part)
    b = TwoPartSpectrum.from_json(scan_model.two_part)
    assert np.allclose(a.psd(23.0), b.psd(23.0))


def test_bad_two_part_block_names_the_key(scan_model):
    data = json.loads(json.dumps(model_to_json(scan_model)))
    data["two_part"]["g"] = data["two_part"]["g"][:-1]
    with pytest.raises(UserError, match=r"m.json: two_part.g has"):
        parse_model(data, "m.json")
    data["two_part"]["tool"][3] = -1.0
    with pytest.raises(UserError, match=r"two_part: key 'tool' must be"):
        parse_model(data, "m.json")


def test_cli_fit_form_calibrated_says_its_base(tmp_path, capsys):
    _, _, out = fit_calibrated_by_cli(tmp_path)
    file_line = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith(str(out))]
    assert "calibrated spectrum on its two-part base (600 iterations)" in file_line[0]
    m = json.loads(out.read_text())
    assert m["free_form"]["form"] == "calibrated" and "two_part" in m
    assert m["provenance"]["two_part_iterations"] == 600


def gap_psd(f_hz, v_mm_s):
    """A rough band below 8 /mm through a fixed 150 Hz mode, its level a power law in
    speed (a spatial process's is), over a white sensor floor whose level does not depend
    on speed: above 8 v Hz there is only the floor."""
    tool = 1.0 / (1.0 + ((f_hz - 150.0) / 50.0) ** 2) + 0.02
    k = f_hz / v_mm_s
    surface = np.where(k < 8.0, 1.0 / np.maximum(k, 0.5), 0.0) \
        * (1.0 + 4.0 * np.exp(-((k - 3.0) / 0.3) ** 2))
    return tool * surface * (v_mm_s / 20.0) ** 3 + 2e-3


@pytest.fixture(scope="module")
def gap_fit():
    """Strokes that wander +-1 mm/s around 10, 20, 30 and 40 mm/s: nothing between."""
    rng = np.random.default_rng(11)
    speeds = [c + d for c in (10.0, 20.0, 30.0, 40.0) for d in (-1.0, 0.0, 1.0)]
    runs = [shaped_noise(v, 3.0, rng, gap_psd) for v in speeds]
    return fit_two_part(runs, [np.full(r.size, v) for r, v in zip(runs, speeds, strict=True)],
                        FS, (5.0, 45.0))


def test_spectrum_in_a_gap_between_strokes_matches_the_truth(gap_fit):
    """At 15 and 25 mm/s, 4 mm/s from any data: the level within 0.5 dB of the truth and
    the shape within 1.6 dB rms (smoothed over 10 Hz; 0.5-0.75 at the strokes' own
    speeds, a U fitted on 3 s per speed). Before the log-speed levels, the dropped
    knots and N0: +0.8 to +2.8 dB level, 5 dB rms at 25 mm/s."""
    f = gap_fit.f_hz
    sel = (f >= 20) & (f <= 480)
    for v in (15.0, 25.0):
        err = _db(_smooth(gap_fit.psd(v))[sel]) - _db(_smooth(gap_psd(f, v))[sel])
        assert abs(err.mean()) < 0.5 and np.sqrt(np.mean(err**2)) < 1.6, \
            (v, err.mean(), np.sqrt(np.mean(err**2)))


def test_model_file_keeps_the_fixed_floor(gap_fit, scan_model):
    """N0 goes into the file and back; a file without it is a form no longer rendered."""
    d = gap_fit.to_json()
    assert np.allclose(TwoPartSpectrum.from_json(d).psd(15.0), gap_fit.psd(15.0))
    data = json.loads(json.dumps(model_to_json(scan_model)))
    data["two_part"]["fixed_floor"] = [1.0]
    with pytest.raises(UserError, match=r"m.json: two_part: key 'fixed_floor' must be"):
        parse_model(data, "m.json")
    data["two_part"].pop("fixed_floor")
    with pytest.raises(UserError, match=r"m.json: a two-part base without 'fixed_floor' is "
                       "a form this fydpad no longer renders; refit"):
        parse_model(data, "m.json")


def test_sensor_floor_keeps_its_level_at_every_speed(gap_fit):
    """Where only the floor is (above 8 v Hz), the fitted S stays at the floor from the
    slowest strokes to the fastest, also in the gaps and down to 7 mm/s, where the
    spatial frequencies are ones only the slowest chunks saw."""
    f = gap_fit.f_hz
    for v in (7.0, 9.0, 12.0, 15.0, 20.0, 25.0, 30.0, 35.0, 41.0):
        only_floor = (f > 8.0 * v + 10.0) & (f <= 480)
        if only_floor.sum() < 10:
            continue
        level = _db(np.mean(gap_fit.psd(v)[only_floor]))
        # Before N0: +0.85 dB at 15 mm/s, +6.4 dB at 25.
        assert abs(level - _db(2e-3)) < 0.75, (v, level - _db(2e-3))


def test_levels_beyond_the_end_knots_are_bounded_to_a_power_of_speed():
    """A level the fit leaves unused (the floor n(v) where N0 holds the floor) drifts with
    any slope, ~3 decades per mm/s; continued unbounded below the first knot it stood
    1e13 at 5 mm/s and a held-out stroke's ramps rendered +90 dB. Beyond the end knots the
    slope in log level per log speed is bounded (v^+-4); within them, and a gentle slope
    beyond them, the levels are untouched."""
    from fydpad.texture.lpc.spectrum import MAX_EXTRAPOLATION_POWER, _hats, _node_levels

    v = np.array([5.0, 10.0, 11.0, 12.0, 30.0, 40.0, 60.0])
    log_knots = np.log([10.0, 12.0, 20.0, 40.0])
    drift = np.log([1e-7, 1e-13, 1e-12, 2e-12])  # falls 6 decades from 10 to 12 mm/s
    gentle = np.log([1.0, 1.2, 2.0, 4.0])  # power ~ v: slope 1 at both ends
    phi = _hats(np.log(v), log_knots, clamp=False)
    for levels in (drift, gentle):
        got = _node_levels(levels, np.log(v), log_knots, phi)
        np.testing.assert_allclose(got[1:6], (phi @ levels)[1:6], rtol=1e-12)
    got = np.exp(_node_levels(drift, np.log(v), log_knots, phi))
    assert np.exp((phi @ drift)[0]) > 1e8  # the end segment continued: 1e15 at 5 mm/s
    np.testing.assert_allclose(got[0], 1e-7 * 2.0 ** MAX_EXTRAPOLATION_POWER, rtol=1e-12)
    np.testing.assert_allclose(got[6], 2e-12 * 1.5, rtol=1e-12)  # slope 1 kept
    gentle_out = np.exp(_node_levels(gentle, np.log(v), log_knots, phi))
    np.testing.assert_allclose(gentle_out[[0, 6]], [0.5, 6.0], rtol=1e-12)
