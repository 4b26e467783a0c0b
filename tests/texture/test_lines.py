"""The line spectrum of periodic surfaces (fydpad/texture/lpc/lines.py, line_voice.py).

Ground truth first: strokes synthesized here from a known comb (a period, amplitudes that
follow a tool resonance and the speed, a vanishing harmonic) in noise that is not an AR
process, along a hand's speed; then the generator's surfaces, whose periods are known.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan, hand_speed
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import fit_texture, lines_option
from fydpad.texture.lpc.line_voice import LineVoice
from fydpad.texture.lpc.lines import LineSpectrum, arc_length_mm, fit_lines
from fydpad.texture.lpc.model_file import load_model, save_model
from fydpad.texture.lpc.synthesis import TextureRenderer

FS = 1000.0
PERIOD = 1.7  # mm: none of the generator's
SPEEDS = (10.0, 20.0, 30.0, 40.0)
NOISE = 0.02  # m/s^2 RMS of the broadband part
#: A line's power 20 dB over what the white noise puts in a fit of ~1 Hz bandwidth (a few
#: knots over 10 s): (one-sided density 2 NOISE^2 / FS) x 1 Hz x 100.
STRONG = 100 * 2 * NOISE ** 2 / FS


def true_amplitude(n: np.ndarray, v: float) -> np.ndarray:
    """The comb's truth: 1/n, every 5th harmonic absent, through a 150 Hz mode (Q 3),
    growing as v^2 (an acceleration)."""
    f = n * v / PERIOD
    mode = 1.0 / np.abs(1 - (f / 150.0) ** 2 + 1j * f / (3 * 150.0))
    a = 0.2 / n * mode * (v / 20.0) ** 2
    return np.where(n % 5 == 0, 0.0, a) * (f < 0.99 * FS / 2)


def amplitudes_at(sp: LineSpectrum, v: float) -> np.ndarray:
    """A_n at a speed: linear between the table's rows, as the renderer mixes them."""
    return np.array([np.interp(v, sp.v_mm_s, col) for col in sp.amplitude.T])


def comb_stroke(v_target: float, seed: int, seconds: float = 10.0):
    """(signal, speed, its noise): the comb along a hand's speed, plus noise that is impulsive and
    coloured (sparse taps through a 2nd-order filter and white noise), not AR."""
    rng = np.random.default_rng(seed)
    v = hand_speed(v_target, seconds, FS, rng)
    s = arc_length_mm(v, FS)
    n = np.arange(1, 200)
    y = np.zeros(v.size)
    for k in n:
        amp = true_amplitude(np.array([k]), 1.0)[0]  # nonzero pattern only
        if amp == 0.0:
            continue
        a = np.array([true_amplitude(np.array([k]), float(x))[0] for x in v[::50]])
        a = np.interp(np.arange(v.size), np.arange(0, v.size, 50), a)
        y += a * np.cos(2 * np.pi * k * s / PERIOD + 0.3 * k)
    taps = (rng.random(v.size) < 0.02) * rng.standard_normal(v.size) * 0.3
    b, a = ss.butter(2, [60, 200], "bandpass", fs=FS)
    noise = ss.lfilter(b, a, taps) + NOISE * rng.standard_normal(v.size)
    return y + noise, v, noise


@pytest.fixture(scope="module")
def comb():
    strokes = [comb_stroke(v, seed) for v in SPEEDS for seed in (1, 2)]
    return strokes, fit_lines([y for y, _, _ in strokes], [v for _, v, _ in strokes], FS,
                              (5.0, 45.0))


def test_the_period_is_found_to_1e5(comb):
    _, fit = comb
    assert fit.spectrum is not None, fit.note
    assert fit.period_mm == pytest.approx(PERIOD, rel=1e-5)


def test_amplitudes_match_the_truth_where_the_lines_stand_out(comb):
    """At the fitted speeds the harmonics 10 dB or more over the noise's level in their
    band are within 1 dB (median) and 2 dB (all) of the truth; the vanishing 5th, 10th..
    are 20 dB or more below their neighbours where those stand out."""
    _, fit = comb
    sp = fit.spectrum
    for v in SPEEDS:
        n = np.arange(1, sp.amplitude.shape[1] + 1)
        truth = true_amplitude(n, v)
        got = amplitudes_at(sp, v)
        strong = (truth ** 2 / 2 > STRONG) & (truth > 0)
        err = 20 * np.log10(got[strong] / truth[strong])
        assert np.median(np.abs(err)) < 1.0 and np.max(np.abs(err)) < 2.0, (v, err)
        fifth = (n % 5 == 0) & (n < n.size)
        neighbours = np.maximum(truth[n[fifth] - 2], truth[n[fifth]])
        clear = neighbours ** 2 / 2 > STRONG
        ratio = got[fifth][clear] / np.maximum(got[n[fifth] - 2], got[n[fifth]])[clear]
        assert np.all(ratio <= 0.1), (v, ratio)


def test_between_the_strokes_speeds_the_factor_model_holds(comb):
    """15 mm/s lies in the gap between the 10 and 20 mm/s strokes' speeds (12.5-16.5
    mm/s here): strong harmonics within 1 dB of the truth on the median (measured 0.66;
    0.32-0.48 on the strokes' seeds 3-4, 5-6 and 7-8)."""
    err = _errors_at_15(comb)
    assert np.median(np.abs(err)) < 1.0, err


@pytest.mark.xfail(strict=True, reason="the 16th harmonic (141 Hz) 2.15 dB under the "
                   "truth (measured)")
def test_between_the_strokes_speeds_every_strong_harmonic_is_within_2_db(comb):
    err = _errors_at_15(comb)
    assert np.max(np.abs(err)) < 2.0, err


def _errors_at_15(comb) -> np.ndarray:
    """dB of the strong harmonics at 15 mm/s against the truth."""
    sp = comb[1].spectrum
    n = np.arange(1, sp.amplitude.shape[1] + 1)
    truth, got = true_amplitude(n, 15.0), amplitudes_at(sp, 15.0)
    strong = truth ** 2 / 2 > STRONG
    return 20 * np.log10(got[strong] / truth[strong])


def test_between_the_strokes_speeds_the_generators_grating_keeps_its_level():
    """R1 from two strokes at each of 10-40 mm/s: at 14-16 mm/s, between the 10 and
    20 mm/s strokes, the lines' power per band (20-45, 45-80, 80-130 Hz) against lines
    fitted on four 12 s strokes at 15 mm/s (the truth): within 0.75 dB on average over
    the three speeds (measured +0.34, -0.09, +0.44; +1.70, +1.28, +1.81 when the speed
    level g(v) of the factor model bridged the gap as its smoothing penalty bent it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = fit_texture([generate_scan("R1", v, 10.0, seed=1 + j)
                             for v in SPEEDS for j in (0, 1)])
        truth_scans = [generate_scan("R1", 15.0, 12.0, seed=100 + j) for j in range(4)]
        truth = fit_lines([preprocess(sc.acc, FS) for sc in truth_scans],
                          [sc.speed_mm_s for sc in truth_scans], FS, (10.0, 20.0)).spectrum
    got = LineSpectrum.from_json(model.lines, model.surface)
    bands = ((20.0, 45.0), (45.0, 80.0), (80.0, 130.0))
    err = np.zeros((3, len(bands)))
    for i, v in enumerate((14.0, 15.0, 16.0)):
        n = np.arange(1, min(got.amplitude.shape[1], truth.amplitude.shape[1]) + 1)
        f = n * v / truth.period_mm
        a, b = (amplitudes_at(s, v)[:n.size] ** 2 for s in (got, truth))
        for j, (lo, hi) in enumerate(bands):
            band = (f >= lo) & (f < hi)
            err[i, j] = 10 * np.log10(a[band].sum() / b[band].sum())
    assert np.all(np.abs(err.mean(axis=0)) < 0.75), err


def test_the_residual_is_what_the_lines_leave(comb):
    """On the samples the stochastic fit may use (most of each stroke), the residual less
    the noise (taps and white noise) is what the fits got wrong: the noise they caught
    (a few knots per harmonic over 10 s: 3-7 % of it here) and the lines' own error; at
    most 10 % of the noise's power and 30 dB below the lines' (the strongest stroke:
    a fundamental 34 dB over the noise, its error -39 dB). The residual keeps at least
    90 % of the noise's power."""
    strokes, fit = comb
    for (y, _, noise), r, keep in zip(strokes, fit.residuals, fit.keep, strict=True):
        assert keep.mean() > 0.7
        lines = np.mean((y - noise)[keep] ** 2)
        noise_power = np.mean(noise[keep] ** 2)
        left = np.mean((r - noise)[keep] ** 2)
        assert left < 0.1 * noise_power + 1e-3 * lines, (left, noise_power, lines)
        assert np.mean(r[keep] ** 2) > 0.9 * noise_power


@pytest.mark.parametrize("name, period", [("R1", 3.90), ("R2", 2.15), ("mesh_steel", 0.6),
                                          ("aluminum_knurl", 1.0), ("canvas", 1.2)])
def test_the_generators_periodic_surfaces_are_found(name, period):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scans = [generate_scan(name, s, 6.0, seed=3) for s in SPEEDS]
        fit = fit_lines([preprocess(sc.acc, FS) for sc in scans],
                        [sc.speed_mm_s for sc in scans], FS, (5.0, 45.0))
    assert fit.spectrum is not None, fit.note
    assert fit.period_mm == pytest.approx(period, rel=1e-4)
    assert fit.share > 0.9  # the generator's combs: 96-99 % of the power


def test_the_table_is_finite_when_one_strokes_fit_makes_a_line(tmp_path):
    """mesh_steel, two 10 s strokes per speed (seeds 5-6): rows where only one stroke's
    own fit made a harmonic present once gave a negative power, NaN in the factor model
    and a file no reader accepts; every amplitude is finite and the file reads back."""
    scans = [generate_scan("mesh_steel", s, 10.0, seed=5 + j) for s in SPEEDS for j in (0, 1)]
    model = fit_texture(scans)
    assert np.all(np.isfinite(np.asarray(model.lines["amplitude"])))
    load_model(save_model(model, tmp_path / "mesh.json"))


def test_a_single_rib_is_one_line():
    """Corduroy: the generator's rib is a 2.5 mm cosine, one spatial line at 4-16 Hz
    (10-40 mm/s) and no comb, which the comb search (3 peaks a stroke, from 15 Hz) never
    found. The single-line search finds the period and models the line alone (its
    harmonics stand nowhere out of the noise: 47 were kept before, each a narrow line
    of noise); the line is most of the power."""
    fit = _lines_of([generate_scan("corduroy", s, 6.0, seed=3) for s in SPEEDS])
    assert fit.spectrum is not None, fit.note
    assert fit.period_mm == pytest.approx(2.5, rel=1e-3)
    assert fit.spectrum.amplitude.shape[1] == 1 and "a rib: one line, no comb" in fit.note
    assert fit.share > 0.3
    # Truth at 40 mm/s (16 Hz): the rib's vertical acceleration (2 pi f)^2 x 0.075 mm =
    # 0.758 m/s^2, x 1.06 for the tangential axes' share (0.3 and 0.18 of it, DFT321
    # keeps the energy), x 1.02 the tool mode (120 Hz, damping 0.15), x 0.99 the 10 Hz
    # high-pass and the tip's smoothing: 0.80 m/s^2 (measured 0.79).
    a40 = amplitudes_at(fit.spectrum, 40.0)[0]
    assert a40 == pytest.approx(0.80, rel=0.1)


def _lines_of(scans) -> object:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_lines([preprocess(sc.acc, FS) for sc in scans],
                         [sc.speed_mm_s for sc in scans], FS, (5.0, 45.0))


def test_a_ribs_residual_is_a_surface_and_gets_the_spectral_form():
    """Corduroy's line holds about half its power; the rest is its roughness through
    the tool, which stretches with speed. So what the line leaves is fitted by the
    calibrated spectrum. Ground truth on strokes at 10, 15, 20, 30 and 40 mm/s: at 15 mm/s
    the held-out stroke meets the target with it (measured +0.03 dB over the ceiling)."""
    from fydpad.texture.evaluation.evaluate import evaluate_scan
    from tests.texture.heldout import held_out

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = [generate_scan("corduroy", v, 8.0, seed=3 + j)
                 for v in (10.0, 15.0, 20.0, 30.0, 40.0) for j in (0, 1)]
        default = fit_texture(train)
    assert default.lines is not None and default.free_form["form"] == "calibrated"
    assert default.provenance["lines"]["share"] < 0.9
    held, mask, ceil = held_out("corduroy", 15.0, default, 12.0, 50, 51)
    over = evaluate_scan(default, held, mask=mask)[0].lsd_db - ceil.lsd_db
    assert over <= 0.25, over


def test_a_combs_residual_gets_the_spectral_form_too():
    """aluminum_knurl: 97 % of the power in its lines; what they leave is fitted by the
    calibrated spectrum as a rib's is. Ground truth at 15 mm/s, between strokes at 10
    and 20 mm/s: the held-out stroke meets the target with it (measured -0.67 dB over
    the ceiling)."""
    from fydpad.texture.evaluation.evaluate import evaluate_scan
    from tests.texture.heldout import held_out

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = [generate_scan("aluminum_knurl", v, 10.0, seed=1 + j)
                 for v in SPEEDS for j in (0, 1)]
        default = fit_texture(train)
    assert default.lines is not None and default.free_form["form"] == "calibrated"
    assert default.provenance["lines"]["share"] > 0.9
    held, mask, ceil = held_out("aluminum_knurl", 15.0, default, 12.0, 50, 51)
    over = evaluate_scan(default, held, mask=mask)[0].lsd_db - ceil.lsd_db
    assert over <= 0.25, over


@pytest.mark.parametrize("seed", [3, 4])
def test_a_rounded_rib_keeps_the_harmonics_that_stand_out(seed):
    """A rounded rib (70 % ridge, smoothed over 0.35 mm): a line and a few harmonics, no
    comb of three peaks a stroke. Its harmonics stand as spatial peaks and are kept
    (one line alone held 58 % of the power); with seed 4 the 2nd harmonic outdoes the
    line in one stroke."""
    from fydpad.synth.texture_scans import Texture

    rib = Texture("round_rib_0.35", period_mm=2.5, ridge_fraction=0.7, relief_mm=0.15,
                  tip_mm=0.35, rough_mm=0.001, resonance_hz=120.0, damping=0.15)
    fit = _lines_of([generate_scan(rib, v, 6.0, seed=seed) for v in SPEEDS])
    assert fit.period_mm == pytest.approx(2.5, rel=1e-3), fit.note
    assert fit.spectrum.amplitude.shape[1] >= 2 and fit.share > 0.95, fit.note


class _Strokes:
    def __init__(self, acc: np.ndarray, v: np.ndarray) -> None:
        self.acc, self.speed_mm_s = acc, v


def test_a_rib_whose_second_harmonic_is_as_loud_is_not_taken_at_half_its_period():
    """A 2.5 mm rib with a 2nd harmonic of the fundamental's acceleration: in some
    strokes the 1.25 mm line is the strongest peak. The period is the rib's, and both
    lines are modelled."""
    scans = []
    for i, v_t in enumerate(SPEEDS):
        rng = np.random.default_rng(10 + i)
        v = hand_speed(v_t, 6.0, FS, rng)
        s = arc_length_mm(v, FS)
        a = 0.075e-3 * (2 * np.pi * v / 2.5) ** 2
        z = a * np.cos(2 * np.pi * s / 2.5) + a * np.cos(4 * np.pi * s / 2.5 + 0.5)
        scans.append(_Strokes(np.column_stack([0.3 * z, 0.15 * z, z])
                              + 0.01 * rng.standard_normal((v.size, 3)), v))
    fit = _lines_of(scans)
    assert fit.period_mm == pytest.approx(2.5, rel=1e-3), fit.note
    assert fit.spectrum.amplitude.shape[1] == 2


def test_a_hum_on_strokes_at_one_speed_is_not_a_rib():
    """A 50 Hz hum on three strokes at one rig speed stands at one spatial frequency in
    every stroke, as a rib's line would; a surface's line moves with the speed, a hum
    does not, so strokes whose speeds do not differ by 20 % make no rib."""
    scans = []
    for seed in (1, 2, 3):
        sc = generate_scan("felt", 20.0, 6.0, seed=seed, hand_variation=0.0)
        sc.acc = sc.acc + 0.2 * np.sin(2 * np.pi * 50.0 * np.arange(sc.acc.shape[0]) / FS
                                       )[:, None]
        scans.append(sc)
    fit = _lines_of(scans)
    assert fit.spectrum is None and "no spatial period" in fit.note, fit.note


def test_a_rib_is_found_among_strokes_too_slow_to_see_it():
    """Corduroy with four strokes at 10-20 mm/s, where the line is below 10 Hz, and
    two at 30-40: only those two see it, and they decide."""
    fit = _lines_of([generate_scan("corduroy", v, 6.0, seed=3 + j)
                     for v, j in ((10, 0), (10, 1), (20, 0), (20, 1), (30, 0), (40, 0))])
    assert fit.period_mm == pytest.approx(2.5, rel=1e-3), fit.note


@pytest.mark.parametrize("name", ["felt", "sandpaper_p80", "sandpaper_p320", "glass",
                                  "wood_grain", "brick", "cork", "rubber"])
def test_surfaces_without_a_period_get_no_lines(name):
    """Random roughness, pits, stick-slip, and wood grain, whose period wanders by 20 %
    from one to the next (no comb survives that, nor a single line in every stroke)."""
    scans = [generate_scan(name, s, 6.0, seed=3) for s in SPEEDS]
    fit = fit_lines([preprocess(sc.acc, FS) for sc in scans],
                    [sc.speed_mm_s for sc in scans], FS, (5.0, 45.0))
    assert fit.spectrum is None and "no spatial period" in fit.note, fit.note
    assert all(k.all() for k in fit.keep)


def test_fit_texture_without_lines_is_the_model_it_was(tmp_path):
    """A surface without a period: no 'lines' block, a version-1 file (every reader since
    the first reads it)."""
    scans = [generate_scan("felt", s, 6.0, seed=1) for s in SPEEDS]
    auto = fit_texture(scans, order=60)
    assert auto.lines is None and "no spatial period" in auto.provenance["lines"]["note"]
    data = json.loads(save_model(auto, tmp_path / "felt.json").read_text())
    assert data["format_version"] == 1 and "lines" not in data


@pytest.fixture(scope="module")
def r2_model(tmp_path_factory):
    scans = [generate_scan("R2", s, 6.0, seed=1) for s in SPEEDS]
    model = fit_texture(scans)
    path = save_model(model, tmp_path_factory.mktemp("lines") / "R2.json")
    return model, path


def test_a_model_with_lines_is_a_version_2_file_read_back(r2_model):
    model, path = r2_model
    data = json.loads(path.read_text())
    assert data["format_version"] == 2 and data["lines"]["period_mm"] == pytest.approx(2.15,
                                                                                       rel=1e-4)
    back = load_model(path)
    a, b = LineSpectrum.from_json(back.lines, "x"), LineSpectrum.from_json(model.lines, "y")
    np.testing.assert_allclose(a.amplitude, b.amplitude, rtol=1e-5, atol=1e-9)
    # With lines the spectral form is fitted on what they leave.
    assert back.free_form["form"] == "calibrated" and back.free_form == model.free_form
    assert back.provenance["lines"]["share"] > 0.9


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(format_version=1), r"'lines' needs 'format_version' 2"),
    (lambda d: d.update(format_version=3), r"format_version"),
    (lambda d: d["lines"].update(period_mm=-1), r"lines\.period_mm"),
    (lambda d: d["lines"].update(period_mm=True), r"lines\.period_mm"),
    (lambda d: d["lines"]["amplitude"].pop(), r"lines\.amplitude"),
    (lambda d: d["lines"].update(phase_rad=[0.0]), r"lines\.amplitude"),
    (lambda d: d["lines"]["amplitude"][0].__setitem__(0, -1.0), r"lines\.amplitude"),
    (lambda d: d["lines"].update(v_mm_s=d["lines"]["v_mm_s"][::-1]), r"lines\.v_mm_s"),
    (lambda d: d["lines"].pop("phase_rad"), r"missing key 'lines\.phase_rad'"),
    (lambda d: d["lines"].update(v_mm_s="fast"), r"lines\.v_mm_s"),
    (lambda d: d.update(lines=[1, 2]), r"'lines' must be an object"),
])
def test_a_bad_lines_block_is_an_error_naming_the_key(r2_model, tmp_path, edit, message):
    data = json.loads(r2_model[1].read_text())
    edit(data)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"bad\.json.*" + message):
        load_model(bad)


def test_a_given_period_is_used_and_refined():
    """lines=2.16 (0.5 % off): refined to the true 2.15 mm and kept; 'off' fits none; a
    period that is not a positive number is an error."""
    scans = [generate_scan("R2", s, 6.0, seed=1) for s in SPEEDS]
    fit = fit_lines([preprocess(sc.acc, FS) for sc in scans], [sc.speed_mm_s for sc in scans],
                    FS, (5.0, 45.0), period_mm=2.16)
    assert fit.period_mm == pytest.approx(2.15, rel=1e-4) and fit.spectrum is not None
    assert lines_option("off") == "off" and lines_option("2.16") == 2.16
    for bad in ("wide", -2.0, float("nan")):
        with pytest.raises(UserError, match="lines"):
            fit_texture(scans, lines=bad)


def _one_line_spectrum(amplitude: float, harmonic: int, period: float = 1.0) -> LineSpectrum:
    v = np.arange(5.0, 45.5, 0.5)
    amp = np.zeros((v.size, harmonic))
    amp[:, harmonic - 1] = amplitude
    return LineSpectrum(period, v, amp, np.zeros(harmonic))


def test_a_line_is_rendered_at_its_frequency_and_level():
    """One harmonic (n = 12 of a 1 mm period) at 30 mm/s sounds at 360 Hz with its
    amplitude (RMS A / sqrt 2 within 0.5 %); what the wavetable's interpolation adds
    elsewhere is 30 dB or more below it."""
    voice = LineVoice(_one_line_spectrum(0.4, 12), FS)
    y = voice.block(np.full(20_000, 30.0))
    assert np.sqrt(np.mean(y ** 2)) == pytest.approx(0.4 / math.sqrt(2), rel=5e-3)
    f, p = ss.welch(y, FS, nperseg=1000)
    peak = int(np.argmax(p))
    assert f[peak] == pytest.approx(360.0, abs=1.0)
    away = np.abs(f - 360.0) > 5.0
    assert 10 * np.log10(p[away].max() / p[peak]) < -30.0


def test_tick_and_block_give_the_same_samples_along_a_hands_stroke(r2_model):
    model, _ = r2_model
    v = generate_scan("R2", 25.0, 3.0, seed=9).speed_mm_s
    a = TextureRenderer(model, seed=4)
    b = TextureRenderer(model, seed=4)
    ticks = np.array([a.tick(float(x)) for x in v])
    np.testing.assert_allclose(ticks, b.block(v), rtol=0, atol=1e-12)
    voice = LineVoice(LineSpectrum.from_json(model.lines, "x"), FS)
    again = LineVoice(LineSpectrum.from_json(model.lines, "x"), FS)
    np.testing.assert_allclose([voice.tick(float(x)) for x in v], again.block(v), atol=1e-12)


def test_the_comb_follows_the_speed_and_falls_silent_without_contact(r2_model):
    """At a constant 20 mm/s the strongest lines of R2's rendering sit on multiples of
    20 / 2.15 = 9.30 Hz; without contact the output goes to zero within the gain ramp,
    and a reset and reseed restart the lines with the noise (the same samples twice)."""
    model, _ = r2_model
    r = TextureRenderer(model, seed=0)
    r.warmup(20.0, 0.5)
    y = r.block(20.0, True, 8000)
    f, p = ss.welch(y, FS, nperseg=4000)
    top = f[np.argsort(p)[::-1][:6]]
    assert np.all(np.abs(top / (20.0 / 2.15) - np.rint(top / (20.0 / 2.15))) < 0.06), top
    quiet = r.block(20.0, False, 200)
    assert np.max(np.abs(quiet[50:])) < 1e-3 * np.std(y)
    r.reset()
    r.reseed(7)
    first = r.block(np.full(500, 20.0))
    r.reset()
    r.reseed(7)
    np.testing.assert_array_equal(first, r.block(np.full(500, 20.0)))


def test_the_station_renders_the_lines_from_the_centroid(r2_model):
    """The station's texture term (the model file opened as the render process opens it,
    centroid -> the station's 10 Hz speed -> the LPC family's tick) on a finger moving at
    20 mm/s: its strongest line on a multiple of 9.30 Hz."""
    from fydpad.station.texture_source import open_texture, tick_speed

    src = open_texture(str(r2_model[1]), FS)
    speed = tick_speed()
    out = []
    for k in range(6000):
        t = k / FS
        speed.sample(t, 20.0 * t, 0.0, True)
        out.append(src.tick(t, True, 20.0 * t, 0.0, speed.tick(1 / FS), 1.0)[0])
    f, p = ss.welch(np.asarray(out[2000:]), FS, nperseg=2000)
    top = f[int(np.argmax(p))]
    assert abs(top / (20.0 / 2.15) - round(top / (20.0 / 2.15))) < 0.06, top


def test_a_constant_speed_rig_keeps_its_lines():
    """Strokes at a constant speed (a motorised rig: no hand's wander) put all their data
    in one speed row: the lines are kept there (not vetoed by rows without data) and the
    rendering along each stroke has its recording's power within 1 dB."""
    scans = [generate_scan("R2", s, 6.0, seed=1, hand_variation=0.0) for s in SPEEDS]
    model = fit_texture(scans)
    assert model.lines is not None
    for sc in scans:
        rec = preprocess(sc.acc, FS)[1000:-1000]
        r = TextureRenderer(model, seed=0)
        r.warmup(float(sc.speed_mm_s[1000]), 0.5)
        syn = r.block(sc.speed_mm_s)[1000:-1000]
        assert abs(10 * np.log10(np.mean(syn ** 2) / np.mean(rec ** 2))) < 1.0


def test_a_rig_at_one_speed_with_no_tolerance_gets_its_lines():
    """One speed, tolerance 0: the lines' speed grid has a single row (the factor
    model's smoothing has nothing to bend; it raised 'Offset 2 out of bounds' there)."""
    scan = generate_scan("R1", 20.0, 6.0, seed=1, hand_variation=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = fit_lines([preprocess(scan.acc, FS)], [scan.speed_mm_s], FS, (20.0, 20.0))
    assert fit.spectrum is not None
    assert fit.spectrum.period_mm == pytest.approx(3.9, rel=1e-4)


def test_above_the_tables_fastest_speed_the_lines_hold_their_pitch():
    """The table keeps every harmonic in band up to its fastest speed (45 mm/s here);
    faster, the lines hold that pitch and level (as the process is clamped) instead of
    folding back from above Nyquist: 90 mm/s renders what 45 does."""
    sp = _one_line_spectrum(0.4, 10)  # 10 x 45 / 1 mm = 450 Hz at the top
    fast = LineVoice(sp, FS).block(np.full(4000, 90.0))
    top = LineVoice(sp, FS).block(np.full(4000, 45.0))
    np.testing.assert_allclose(fast, top, atol=1e-12)
    voice = LineVoice(sp, FS)
    np.testing.assert_allclose([voice.tick(90.0) for _ in range(100)], top[:100], atol=1e-12)


def test_a_lines_block_the_renderer_cannot_play_is_refused():
    """Uneven speed steps (the renderer indexes rows by one step) and absurd periods are
    errors on reading, not a wrong sound or a crash in the 1 kHz loop."""
    good = _one_line_spectrum(0.4, 3).to_json()
    for key, value in (("v_mm_s", [5.0, 10.0, 40.0]), ("period_mm", 1e-310),
                       ("period_mm", 5e3)):
        d = dict(good)
        d[key] = value
        if key == "v_mm_s":
            d["amplitude"] = [[0.0, 0.0, 1.0]] * 3
        with pytest.raises(UserError, match=f"lines\\.{key}"):
            LineSpectrum.from_json(d, "m.json")


def test_a_given_period_is_kept_even_outside_the_search_range():
    """--lines PERIOD is used as given (refined), whatever the automatic search would
    consider: a 0.04 mm period (below its 0.05 mm) is fitted and said to hold little."""
    scans = [generate_scan("R2", s, 4.0, seed=1) for s in (20.0, 30.0)]
    fit = fit_lines([preprocess(sc.acc, FS) for sc in scans], [sc.speed_mm_s for sc in scans],
                    FS, (15.0, 35.0), period_mm=0.04)
    note = fit.note
    assert fit.period_mm == pytest.approx(0.04, rel=0.03), note
    assert "no spatial period" not in note


def test_a_speed_that_is_not_finite_is_silence_in_both_paths(r2_model):
    model, _ = r2_model
    v = np.full(300, 25.0)
    v[100:200] = np.inf
    a, b = TextureRenderer(model, seed=1), TextureRenderer(model, seed=1)
    np.testing.assert_allclose([a.tick(float(x)) for x in v], b.block(v), atol=1e-12)


def test_a_line_seen_at_one_edge_row_is_not_carried_across_a_gap():
    """_fill with a factor model that climbs 5 dB per row across rows without data: a
    harmonic seen only at the last row of a run of data (a stroke's fastest instants)
    keeps its measured row and nothing in the gap (carried, it grew 15 dB over its one
    measurement on canvas); seen at two rows, or at an isolated row (a constant-speed
    rig), it is carried by the model."""
    from fydpad.texture.lpc.lines import _fill

    rows = 30
    data = np.zeros(rows, bool)
    data[5:14] = True  # a 10 mm/s stroke's rows
    data[24:30] = True  # a 20 mm/s stroke's rows
    model = 10.0 ** (np.arange(rows) * 0.5)  # +5 dB per row
    power = np.zeros(rows)
    present = np.zeros(rows, bool)
    present[13], power[13] = True, model[13]  # seen at the run's top row only
    out = _fill(power, present, data, model)
    assert out[13] == power[13] and not out[14:24].any()

    present[12], power[12] = True, model[12]  # seen at two rows: carried across the gap
    out = _fill(power, present, data, model)
    assert out[18] > power[13]

    rig = np.zeros(rows, bool)
    rig[[5, 15, 25]] = True  # a constant-speed rig: isolated rows of data
    present = np.zeros(rows, bool)
    present[5] = True
    power = np.where(present, model, 0.0)
    out = _fill(power, present, rig, model)
    assert out[10] > 0.0  # carried from its one row towards the next rig speed


def test_the_residual_is_not_louder_than_the_stroke_near_nyquist():
    """Taking a line out can only take power away where the line was fitted well; near
    Nyquist a stroke's fit over-states its harmonics (the decimation filter's roll-off
    crosses a harmonic's speed range faster than its knots follow), and R1's 40 mm/s
    strokes' residuals stood up to 6 dB over the strokes at 470-500 Hz (mean +3.6 dB),
    which the all-pole part then rendered. Subtracting only below the table's taper
    (96 % of Nyquist): measured mean +0.37 dB, at most +1.0."""
    train = [generate_scan("R1", s, 10.0, seed=1 + j) for s in SPEEDS for j in range(2)]
    ys = [preprocess(t.acc, FS) for t in train]
    fit = fit_lines(ys, [t.speed_mm_s for t in train], FS, (5.0, 45.0))
    assert fit.spectrum is not None
    for i in (6, 7):  # the 40 mm/s strokes
        keep = fit.keep[i]
        f, p_y = ss.welch(ys[i][keep], FS, nperseg=250)
        _, p_r = ss.welch(fit.residuals[i][keep], FS, nperseg=250)
        sel = f >= 468
        excess = 10 * np.log10(p_r[sel] / p_y[sel])
        assert excess.mean() < 1.0 and excess.max() < 2.0, excess.round(1)
