"""The calibrated spectrum (fydpad/texture/lpc/spectrum.py) against ground truth.

Data: strokes whose speed wanders (0.8-1.2 x the target, a new speed every 0.5 s) with
Gaussian noise shaped to a known S(f, v) that the two-part model cannot represent: two
spatial bands with different speed laws (one falls with speed, one rises steeply above
25 mm/s, as a band edge reaching a sharp tool mode switches a texture's vibration on),
through a fixed mode.
"""

from __future__ import annotations

import argparse
import json
import warnings
from dataclasses import replace

import numpy as np
import pytest

from fydpad.commands import texture
from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.family import runs as mask_runs
from fydpad.texture.lpc.analysis import is_stable
from fydpad.texture.lpc.fit import fit_texture
from fydpad.texture.lpc.model_file import load_model, model_to_json, parse_model, save_model
from fydpad.texture.lpc.spectrum import (
    RENDER_SMEAR_MM_S,
    CalibratedSpectrum,
    chunk_periodograms,
    fit_calibrated,
    fit_two_part,
    spectrum_of,
)
from fydpad.texture.lpc.synthesis import TextureRenderer

FS = 1000.0
SPEEDS = (10.0, 20.0, 30.0, 40.0)


def true_psd(f_hz, v_mm_s):
    """Band a at 4 /mm (level ~ 1/v), band b at 10 /mm (level a sigmoid in v centred on
    25 mm/s), both through a fixed 150 Hz mode; not T(f) U(f/v) g(v) + N(f) n(v)."""
    f = np.asarray(f_hz, float)
    a = 10.0 * (20.0 / v_mm_s) * np.exp(-((f / v_mm_s - 4.0) / 0.5) ** 2)
    b = 10.0 / (1.0 + np.exp(-(v_mm_s - 25.0) / 2.0)) * np.exp(-((f / v_mm_s - 10.0) / 0.8) ** 2)
    mode = 1.0 + 2.0 / (1.0 + ((f - 150.0) / 30.0) ** 2)
    return (a + b + 0.05) * mode + 1e-3


def stroke(target_mm_s, seconds, rng, seg_s=0.5):
    """Noise shaped to S at a piecewise-constant speed drawn in 0.8-1.2 x the target."""
    m = int(seg_s * FS)
    f = np.fft.rfftfreq(m, 1 / FS)
    xs, vs = [], []
    for _ in range(int(seconds / seg_s)):
        v = target_mm_s * rng.uniform(0.8, 1.2)
        spec = (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) / np.sqrt(2)
        xs.append(np.fft.irfft(spec * np.sqrt(true_psd(f, v) * m), m))
        vs.append(np.full(m, v))
    return np.concatenate(xs), np.concatenate(vs)


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(5)
    runs = [stroke(v, 10.0, rng) for v in SPEEDS for _ in range(2)]
    x, v = [r[0] for r in runs], [r[1] for r in runs]
    two = fit_two_part(x, v, FS, (5.0, 45.0))
    by: dict[float, list] = {}
    for xi, vi in runs:
        for s in SPEEDS:  # the runs of 0.25 s or more within 5 mm/s of each speed
            by.setdefault(float(s), []).extend(
                (xi[a:b], vi[a:b]) for a, b in mask_runs(np.abs(vi - s) <= 5.0, 250))
    return {"two": two, "calibrated": fit_calibrated(by, two),
            "by": by,
            "held": {t: t * np.random.default_rng(7).uniform(0.8, 1.2, 24)
                     for t in (20.0, 25.0, 30.0)}}


def _db(x):
    return 10 * np.log10(x)


def _smooth(p):
    """Mean over 5 bins (10 Hz): the fit's per-bin scatter averaged down, its bias kept."""
    return np.convolve(p, np.ones(5) / 5, mode="same")


def _error_db(spec, speeds, f):
    """RMS dB error over 20-480 Hz of the spectrum averaged over a stroke's speeds."""
    sel = (f >= 20) & (f <= 480)
    got = np.mean([spec.psd(float(u)) for u in speeds], axis=0)
    truth = np.mean([true_psd(f, u) for u in speeds], axis=0)
    return float(np.sqrt(np.mean((_db(_smooth(got)) - _db(_smooth(truth)))[sel] ** 2)))


def test_calibrated_spectrum_reproduces_the_pooled_runs_at_each_fitted_speed(fitted):
    """By construction (spectrum.py): S_two C_i, averaged over the runs' own sample
    speeds with the render's +-1 mm/s average, is the runs' mean periodogram. Checked
    here by a different average (every 8th sample, not the 0.25 mm/s histogram)."""
    cal = fitted["calibrated"]
    smear = RENDER_SMEAR_MM_S * np.linspace(-1.0, 1.0, 5)
    for s in (20.0, 30.0):
        runs = [(x, v) for x, v in fitted["by"][s] if x.size >= 512]
        p, _ = chunk_periodograms([x for x, _ in runs], [v for _, v in runs])
        speeds = np.concatenate([v for _, v in runs])[::8]
        # The identity is for S_two C_i (the tent then weighs C_i down away from v_i).
        c_only = np.exp(cal.log_c[list(cal.v_mm_s).index(s)])
        got = np.mean([cal.two.psd(float(u + d)) for u in speeds for d in smear], axis=0) * c_only
        d = _db(got) - _db(p[:, 1:].mean(axis=0))
        # Measured 0.12 / 0.07 dB; without the +-1 mm/s average 0.38 / 0.26.
        assert np.sqrt(np.mean(d**2)) < 0.2, np.sqrt(np.mean(d**2))


def test_calibrated_spectrum_is_closer_to_the_truth_than_two_part_at_fitted_speeds(fitted):
    """Averaged over a held-out stroke's speeds (0.8-1.2 x 20 and 30 mm/s): measured
    0.54 / 0.63 dB against two-part 0.71 / 0.74 dB."""
    f = fitted["two"].f_hz
    for t in (20.0, 30.0):
        cal = _error_db(fitted["calibrated"], fitted["held"][t], f)
        two = _error_db(fitted["two"], fitted["held"][t], f)
        assert cal < two and cal < 0.8, (t, cal, two)


def test_spectrum_between_fitted_speeds_matches_the_truth(fitted):
    """At 25 mm/s (no stroke's target; 20-30 mm/s wander) within 1 dB of the truth
    (measured: calibrated 0.67, two-part 0.84 dB), where the neighbours'
    log mix (a cross-fade of the truth at 20 and 30 mm/s) is 4.5 dB off."""
    f = fitted["two"].f_hz
    held = fitted["held"][25.0]
    mix = np.exp(0.5 * np.log(np.mean([true_psd(f, u) for u in held * 0.8], axis=0))
                 + 0.5 * np.log(np.mean([true_psd(f, u) for u in held * 1.2], axis=0)))
    sel = (f >= 20) & (f <= 480)
    truth = np.mean([true_psd(f, u) for u in held], axis=0)
    mix_db = float(np.sqrt(np.mean((_db(_smooth(mix)) - _db(_smooth(truth)))[sel] ** 2)))
    err = _error_db(fitted["calibrated"], held, f)
    assert err < 1.0 and err < mix_db / 3, (err, mix_db)


@pytest.fixture(scope="module")
def scan_model():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scans = [generate_scan("felt", v, 5.0, seed=1) for v in (10.0, 20.0, 30.0)]
        model = fit_texture(scans, speeds_mm_s=(10.0, 20.0, 30.0), order=60)
    return model


def test_fit_texture_stores_the_spectrum_and_the_renderer_uses_it(scan_model, tmp_path):
    assert scan_model.provenance["spectral_model"] == "free-form"
    assert scan_model.free_form["form"] == "calibrated" and scan_model.two_part is not None
    back = load_model(save_model(scan_model, tmp_path / "m.json"))
    a, b = spectrum_of(back), spectrum_of(scan_model)
    assert np.allclose(a.psd(23.0), b.psd(23.0))
    r = TextureRenderer(back, step_mm_s=1.0, seed=0)
    assert r.table.stable.all() and all(is_stable(p) for p in r.table.polys)
    # At a fitted speed the stored h is the table's filter (one model, two views).
    assert np.allclose(r.table.h[r.table.index(20.0)], back.h[1])
    y = r.block(np.full(2000, 22.0), True, 2000)
    assert np.isfinite(y).all() and y.std() > 0


def test_bad_free_form_block_names_the_key(scan_model):
    data = json.loads(json.dumps(model_to_json(scan_model)))
    bad = json.loads(json.dumps(data))
    bad["free_form"]["log_c"] = bad["free_form"]["log_c"][:-1]
    with pytest.raises(UserError, match=r"free_form: key 'log_c' must be one row per"):
        parse_model(bad, "m.json")
    bad = json.loads(json.dumps(data))
    del bad["two_part"]
    with pytest.raises(UserError, match=r"needs the key 'two_part'"):
        parse_model(bad, "m.json")
    positive = "must be a finite number > 0, not"
    for taper, why in ((0, f"{positive} 0"), (-5, f"{positive} -5"), ("x", f"{positive} 'x'"),
                       (float("inf"), "is not a finite number")):
        bad = json.loads(json.dumps(data))
        bad["free_form"]["taper_mm_s"] = taper
        with pytest.raises(UserError, match=rf"m.json: free_form: key 'taper_mm_s' {why}"):
            parse_model(bad, "m.json")


@pytest.mark.parametrize("change, form", [
    (lambda d: d["free_form"].update(form="free"), "free_form.form 'free'"),
    (lambda d: d["free_form"].update(form="surface"), "free_form.form 'surface'"),
    (lambda d: d["free_form"].update(taper_mm_s=None), "free_form.taper_mm_s null"),
    (lambda d: d.pop("free_form"), "the two-part form"),
    (lambda d: [d.pop("free_form"), d.pop("two_part")], "the pooled form"),
    (lambda d: d["provenance"].update(speed_normalised={"beta": 1.0, "gamma": 0.0}),
     "the speed-normalised form"),
    (lambda d: d.update(format_version=2, lines={"period_mm": 2.15, "v_mm_s": [10.0],
                                                 "amplitude": [[0.1]], "phase_rad": [0.0]}),
     "key 'lines' (a periodic surface's line model"),
])
def test_a_model_of_a_removed_form_fails_in_one_line_naming_it(scan_model, change, form):
    data = json.loads(json.dumps(model_to_json(scan_model)))
    change(data)
    with pytest.raises(UserError) as err:
        parse_model(data, "old.json")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"old.json: {form}"), msg
    assert msg.endswith("no longer renders; refit the model with 'fydpad texture fit "
                        "SCAN.csv ... --out MODEL.json'"), msg
    for method in ("lsf", "reflection", "linear"):
        data = json.loads(json.dumps(model_to_json(scan_model)))
        data["interpolation"] = method
        with pytest.raises(UserError, match=rf"old.json: key 'interpolation' '{method}' is "
                           "not rendered by this fydpad; refit the model with 'fydpad "
                           "texture fit"):
            parse_model(data, "old.json")


def fit_calibrated_by_cli(tmp_path):
    """``fydpad texture fit --form calibrated`` on two generated felt strokes (10, 30
    mm/s): (the parser, the scans, the model file written)."""
    parser = argparse.ArgumentParser(prog="fydpad")
    texture.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["texture", "generate-scans", "--out-dir", str(tmp_path),
                              "--textures", "felt", "--speeds", "10,30", "--strokes", "1",
                              "--seconds", "4"])
    assert args.func(args) == 0
    scans = [str(tmp_path / f"felt_{v}mms_s1.csv") for v in (10, 30)]
    out = tmp_path / "calibrated.json"
    args = parser.parse_args(["texture", "fit", *scans, "--out", str(out), "--speeds",
                              "10,30", "--order", "60", "--form", "calibrated"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert args.func(args) == 0
    return parser, scans, out


def test_cli_fit_form_calibrated(tmp_path):
    parser, scans, out = fit_calibrated_by_cli(tmp_path)
    assert json.loads(out.read_text())["free_form"]["form"] == "calibrated"
    for gone in ("--free-form", "--pooled", "--two-part", "--speed-normalise",
                 "--prewhiten-order"):
        with pytest.raises(SystemExit):
            parser.parse_args(["texture", "fit", *scans, "--out", str(out), gone])


@pytest.fixture(scope="module")
def target_figures():
    """The generator's held-out set-up (one 8 s training stroke per speed, held-out
    8 s strokes seed 100, ceiling seed 200) for the calibrated form:
    {(texture, speed): (corr, lsd, ceiling)}."""
    from fydpad.texture.evaluation.evaluate import evaluate_family
    from fydpad.texture.lpc.family import LpcFamily
    from tests.texture.heldout import held_out

    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in ("R1", "R2", "felt", "glass"):
            # The calibrated form on the whole signal.
            model = fit_texture([generate_scan(name, s, 8.0, seed=1) for s in SPEEDS])
            for v in (20.0, 25.0):
                held, mask, ceil = held_out(name, v, model)
                c, *_ = evaluate_family(LpcFamily(model), held, mask=mask)
                out[(name, v)] = (c.psd_correlation, c.lsd_db, ceil.lsd_db)
    return out


def _check_targets(figures, speed: float) -> None:
    for name in ("R1", "R2", "felt", "glass"):
        corr, lsd, ceil = figures[(name, speed)]
        assert corr >= 0.95, f"{name} at {speed:g} mm/s: correlation {corr:.3f}"
        assert lsd <= ceil + 0.25, f"{name} at {speed:g} mm/s: LSD {lsd:.2f}, ceiling {ceil:.2f}"


def test_targets_between_modelled_speeds_calibrated(target_figures):
    """fit_texture on the whole signal at 25 mm/s: LSD above the
    ceiling R1 -0.46, R2 +0.08, felt -0.35, glass +0.08 dB, corr 0.975-0.986 (measured)."""
    _check_targets(target_figures, 25.0)


@pytest.mark.xfail(strict=True, reason="R2 at 20 mm/s: LSD +0.26 dB over the "
                   "ceiling (measured)")
def test_targets_at_a_modelled_speed_calibrated(target_figures):
    _check_targets(target_figures, 20.0)


def test_the_calibrated_fit_needs_two_speeds_and_chunks_and_says_so():
    """One target speed with data, or runs near each speed long enough for an order-40
    LPC (0.45 s) but not one 0.5 s chunk within the modelled speeds: a one-line error."""
    scans = [generate_scan("felt", 20.0, 6.0, seed=1)]
    with pytest.raises(UserError, match=r"calibrated form needs two or more target speeds "
                       r"with data, these have 1 .*--form paper"):
        fit_texture(scans, speeds_mm_s=(20.0,), order=60)
    short = []
    for s in (20.0, 30.0):
        scan = generate_scan("felt", s, 3.0, seed=1)
        v = np.full_like(scan.speed_mm_s, 60.0)  # far outside the modelled speeds ...
        v[1000:1450] = scan.speed_mm_s[1000:1450]  # ... but for 0.45 s
        short.append(replace(scan, path=f"short{s:g}.csv", speed_mm_s=v))
    with pytest.raises(UserError, match=r"calibrated spectrum: no 0\.5 s chunk"):
        fit_texture(short, speeds_mm_s=(20.0, 30.0), order=40)


def test_a_spectral_forms_table_spans_the_speeds_its_fit_saw(scan_model):
    """The calibrated spectrum renders its own S from where the renderer starts fading
    (the slowest speed less the tolerance, at least half of it) to the fastest plus the
    tolerance, not its slowest and fastest entries held beyond (felt at 40 mm/s, seed set
    A: +2.42 -> +0.33 dB over the ceiling, docs/texture.md); the paper's nearest-model
    grid holds its end models."""
    from fydpad.texture.lpc.interpolation import build_table, table_range

    assert table_range(scan_model) == (5.0, 35.0)
    table = build_table(scan_model)
    assert table.speeds_mm_s[0] == 5.0 and table.speeds_mm_s[-1] == 35.0
    assert not np.allclose(table.polys[table.index(34.0)], table.polys[table.index(30.0)])
    nearest = replace(scan_model, interpolation="nearest")
    assert table_range(nearest) == (10.0, 30.0)


def test_tents_scale_with_the_spacing_of_the_fitted_speeds():
    """At the paper's 10 mm/s steps each correction's tent is 7.5 mm/s wide (the default,
    unchanged); fitted every 5 mm/s it is 3.75, so at a fitted speed its own correction
    has all the weight and no neighbour's adds to it (7.5 mm/s tents summed three)."""
    two = None  # weights do not touch the base
    ten = CalibratedSpectrum(two, np.array([10.0, 20.0, 30.0, 40.0]), np.zeros((4, 3)))
    np.testing.assert_allclose(ten.half_widths_mm_s, 7.5)
    np.testing.assert_allclose(ten.weights(15.0), [1 / 3, 1 / 3, 0, 0])
    five = CalibratedSpectrum(two, np.arange(10.0, 41.0, 5.0), np.zeros((7, 3)))
    np.testing.assert_allclose(five.half_widths_mm_s, 3.75)
    for v in np.arange(10.0, 40.01, 0.25):
        assert five.weights(v).sum() <= 1.0 + 1e-12
    np.testing.assert_allclose(five.weights(15.0), [0, 1, 0, 0, 0, 0, 0])
    uneven = CalibratedSpectrum(two, np.array([10.0, 15.0, 30.0]), np.zeros((3, 3)))
    np.testing.assert_allclose(uneven.half_widths_mm_s, [3.75, 3.75, 7.5])


def test_speeds_fitted_every_5_mm_s_meet_the_target_between(monkeypatch):
    """Ground truth: cork scanned and fitted at 10, 15, 20, 25 and 30 mm/s, a held-out
    stroke at 15 mm/s: +0.15 dB over the ceiling with tents scaled to the spacing, +0.55
    with the 7.5 mm/s tents, which summed three corrections there."""
    import fydpad.texture.lpc.spectrum as free_form
    from fydpad.texture.evaluation.evaluate import evaluate_family
    from fydpad.texture.lpc.family import LpcFamily
    from tests.texture.heldout import held_out

    speeds = (10.0, 15.0, 20.0, 25.0, 30.0)
    train = [generate_scan("cork", v, 8.0, seed=3 + j) for v in speeds for j in (0, 1)]
    over = {}
    for label, per_spacing in (("scaled", free_form.TAPER_PER_SPACING), ("7.5", np.inf)):
        monkeypatch.setattr(free_form, "TAPER_PER_SPACING", per_spacing)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = fit_texture(train, speeds_mm_s=speeds)
        held, mask, ceil = held_out("cork", 15.0, model, 12.0, 50, 51)
        over[label] = evaluate_family(LpcFamily(model), held, mask=mask)[0].lsd_db - ceil.lsd_db
    assert over["scaled"] <= 0.25 < over["7.5"], over
