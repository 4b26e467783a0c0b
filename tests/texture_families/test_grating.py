"""Gratings at a vibrotactile/friction ratio (Ito 2019 4.2): the rendered spatial period
is lambda at any speed, and the energy split follows the ratio's levels."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.families import load_family
from fydpad.texture.families.grating import RATIOS, GratingFamily, estimate_wavelength, level_value
from fydpad.texture.family import constant_stroke
from tests.texture_families.helpers import run_cli


def _peak_hz(y, fs):
    y = y - y.mean()
    f = np.fft.rfftfreq(8 * y.size, 1 / fs)
    p = np.abs(np.fft.rfft(y * np.hanning(y.size), 8 * y.size))
    return f[np.argmax(p)]


def _line_amp(y, fs, f0):
    """Amplitude of the sinusoid at f0 in y (an integer number of periods long)."""
    t = np.arange(y.size) / fs
    return 2 * abs(np.mean(y * np.exp(-2j * np.pi * f0 * t)))


@pytest.mark.parametrize("profile", ["sine", "rect"])
@pytest.mark.parametrize("lam", [0.5, 2.15, 3.90])
@pytest.mark.parametrize("speed", [10.0, 25.0, 40.0])
def test_rendered_peaks_at_speed_over_lambda(profile, lam, speed):
    g = GratingFamily(lam, profile=profile, ratio=(5, 5))
    fs = 1000.0 if speed / lam < 100 else 48_000.0
    fb = constant_stroke(speed, 40 * lam / speed, fs, x0_mm=0.3)
    f0 = speed / lam
    df = fs / (8 * fb.t_s.size)
    for ch in ("vibration", "tension"):
        y = g.render(fb, ch)
        assert abs(_peak_hz(y, fs) - f0) <= max(df, 0.002 * f0), (ch, _peak_hz(y, fs), f0)
    # The spatial period is lambda: the signal repeats after lambda of travel.
    n = round(lam / speed * fs)
    if abs(n - lam / speed * fs) < 1e-6:
        v = g.render(fb, "vibration")
        np.testing.assert_allclose(v[n:], v[:-n], atol=1e-9)


def test_electrostatic_voltage_has_period_two_lambda_and_force_lambda():
    g = GratingFamily(2.0, profile="sine", ratio=(0, 10))
    fb = constant_stroke(20.0, 4.0, 48_000.0)
    assert _peak_hz(g.render(fb, "audio"), 48_000.0) == pytest.approx(5.0, abs=0.05)
    fe = g.force_e(fb.x_mm)
    np.testing.assert_allclose(fe, g.mu * (g.load_n + g.k_n_per_v2 * g.B_v ** 2 / 2 * (
        1 + np.cos(2 * np.pi * fb.x_mm / 2.0))), rtol=1e-12)  # eq. 4


@pytest.mark.parametrize("profile", ["sine", "rect"])
def test_energy_split_follows_the_ratio(profile):
    """Levels linear in force between level 1 and 10, level 0 off; measured from the
    rendered forces' fundamental at speed / lambda for all 11 ratios."""
    lam, speed, fs = 2.0, 20.0, 1000.0
    fb = constant_stroke(speed, 20 * lam / speed, fs)
    f0 = speed / lam
    ref = GratingFamily(lam, profile=profile, ratio=(10, 0))
    unit_v = _line_amp(ref.render(fb, "force"), fs, f0) / ref.A_n
    ref_f = GratingFamily(lam, profile=profile, ratio=(0, 10))
    unit_f = _line_amp(ref_f.force_e(fb.x_mm), fs, f0) / ref_f.Fe_mod_n
    for v, f in RATIOS:
        g = GratingFamily(lam, profile=profile, ratio=(v, f), vib_levels_n=(0.05, 0.5),
                          friction_levels_n=(0.02, 0.2))
        av = _line_amp(g.render(fb, "force"), fs, f0) / unit_v
        af = _line_amp(g.force_e(fb.x_mm), fs, f0) / unit_f
        assert av == pytest.approx(level_value(v, 0.05, 0.5), abs=1e-6)
        assert af == pytest.approx(level_value(f, 0.02, 0.2), abs=1e-6)
    # With levels proportional to the level number the split is the ratio itself.
    for v, f in RATIOS[1:-1]:
        g = GratingFamily(lam, profile=profile, ratio=(v, f), vib_levels_n=(0.05, 0.5),
                          friction_levels_n=(0.05, 0.5))
        ev = _line_amp(g.render(fb, "force"), fs, f0) / unit_v
        ef = _line_amp(g.force_e(fb.x_mm), fs, f0) / unit_f
        assert ev / (ev + ef) == pytest.approx(v / 10, abs=1e-6)


def test_default_ratio_is_8_2_from_1_mm():
    assert GratingFamily(1.0).ratio == (8, 2) and GratingFamily(3.9).ratio == (8, 2)
    assert GratingFamily(0.5).ratio == (6, 4)


def test_rectangular_profile_has_90_percent_ridge_and_the_10th_harmonic_vanishes():
    g = GratingFamily(3.90, profile="rect", ridge_fraction=0.9, edge_mm=0.0)
    x = np.arange(0, 3.90 * 50, 0.001)
    p = g.p(x)
    assert np.mean(p > 0) == pytest.approx(0.9, abs=0.002)
    assert abs(p.mean()) < 1e-3
    spec = np.abs(np.fft.rfft(p)) / p.size
    k1 = 50  # 50 periods in the window: harmonic h at bin 50 h
    assert spec[10 * k1] < 0.02 * spec[9 * k1] and spec[10 * k1] < 0.02 * spec[11 * k1]


@pytest.mark.parametrize(("name", "lam"), [("R1", 3.90), ("R2", 2.15)])
def test_wavelength_estimated_from_scans(name, lam):
    scans = [generate_scan(name, v, 6.0, seed=1) for v in (20.0, 30.0)]
    assert estimate_wavelength(scans) == pytest.approx(lam, rel=0.01)


def test_cli_fit_names_an_option_the_grating_does_not_take(tmp_path):
    with pytest.raises(UserError, match=r"fit --kind grating: .*argument 'ridge'"):
        run_cli("fit", "--kind", "grating", "--wavelength-mm", "2.15", "--set", "ridge=0.8",
                "--out", str(tmp_path / "g.json"))
    assert not (tmp_path / "g.json").exists()


@pytest.mark.parametrize(("setting", "says"), [
    ("profile=triangle", "profile must be one of"),
    ("ridge_fraction=1.5", r"ridge fraction must be in \(0, 1\), got 1.5"),
])
def test_cli_fit_refuses_a_value_no_grating_has_before_writing(tmp_path, setting, says):
    """A value the family cannot render is a one-line error at the fit, not a file that
    then refuses to load."""
    with pytest.raises(UserError, match=f"^fit --kind grating: {says}"):
        run_cli("fit", "--kind", "grating", "--wavelength-mm", "2.15", "--set", setting,
                "--out", str(tmp_path / "g.json"))
    assert not (tmp_path / "g.json").exists()


def test_cli_fit_parametric_and_synth(tmp_path):
    out = tmp_path / "g.json"
    assert run_cli("fit", "--kind", "grating", "--wavelength-mm", "2.15", "--ratio", "7:3",
                   "--out", str(out)) == 0
    m = json.loads(out.read_text())
    assert m["kind"] == "grating" and m["ratio"] == [7, 3] and m["profile"] == "rect"
    fam = load_family(str(out))
    assert fam.wavelength_mm == 2.15
    assert run_cli("synth", str(out), "--speed-mm-s", "21.5", "--seconds", "1",
                   "--out", str(tmp_path / "v.csv")) == 0
    from vision.recording import read_csv_columns

    cols = read_csv_columns(tmp_path / "v.csv", ("t_s", "a"))  # the vibration, m/s^2
    assert _peak_hz(cols["a"], 1000.0) == pytest.approx(10.0, abs=0.2)


@pytest.mark.parametrize("profile", ["sine", "rect"])
def test_tick_path_equals_offline_render(profile):
    """The station's per-tick floats give what the offline arrays give (positions given
    every tick, so no extrapolation is involved)."""
    g = GratingFamily(2.15, profile=profile, ratio=(7, 3))
    fb = constant_stroke(23.0, 0.5, 1000.0, x0_mm=1.0)
    vib, ten = g.render(fb, "vibration"), g.render(fb, "tension")
    ticks = np.array([g.tick(t, True, x, 0.0, 23.0, 1.0) for t, x in zip(fb.t_s, fb.x_mm,
                                                                            strict=True)])
    np.testing.assert_allclose(ticks[:, 0], vib, atol=1e-9)
    np.testing.assert_allclose(ticks[:, 1], ten, atol=1e-9)
