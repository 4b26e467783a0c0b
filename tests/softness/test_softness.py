"""Softness fits, the table and its inversion, specimens and the live estimator, on data
with a known ground truth."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from fydpad.softness import (
    SPECIMENS,
    LiveStiffness,
    SoftnessError,
    SoftnessTable,
    SoftnessWarning,
    characterise_fabric,
    fit_specimen,
    fit_through_origin,
    load_table,
    save_table,
    specimen,
    stiffness_over_presses,
)

THETAS = np.array([0.0, 0.3, 0.6, 0.9, 1.2])
KS = np.array([0.262, 0.41, 0.60, 0.81, 1.04])  # the paper's range at its ends


def indenter_data(rng, thetas=THETAS, ks=KS, noise_n=0.03, n=25, dmax=10.0):
    th, d, f = [], [], []
    for t, k in zip(thetas, ks, strict=True):
        dd = np.linspace(0.3, dmax, n)
        th.append(np.full(n, t))
        d.append(dd)
        f.append(k * dd + rng.normal(0, noise_n, n))
    return np.concatenate(th), np.concatenate(d), np.concatenate(f)


def test_through_origin_fit_recovers_slope_and_r2():
    d = np.linspace(0, 10, 11)
    fit = fit_through_origin(d, 0.7 * d)
    assert fit.k_n_per_mm == pytest.approx(0.7, rel=1e-12)
    assert fit.r2 == pytest.approx(1.0)
    assert fit.n == 11
    # A line with an offset: the through-origin fit is worse than perfect, R^2 < 1.
    fit2 = fit_through_origin(d, 0.7 * d + 1.0)
    assert fit2.r2 < 0.99
    # Hand-computed: k = sum(d f) / sum(d^2).
    f = np.array([1.0, 2.5, 2.9])
    dd = np.array([1.0, 2.0, 3.0])
    assert fit_through_origin(dd, f).k_n_per_mm == pytest.approx((1 + 5 + 8.7) / 14)


def test_fit_rejects_degenerate_input():
    with pytest.raises(SoftnessError, match="at least 2"):
        fit_through_origin([1.0], [1.0])
    with pytest.raises(SoftnessError, match="zero"):
        fit_through_origin([0.0, 0.0], [1.0, 2.0])
    with pytest.raises(SoftnessError, match="length"):
        fit_through_origin([1.0, 2.0], [1.0])


def test_characterise_recovers_k_per_theta():
    rng = np.random.default_rng(3)
    table = characterise_fabric(*indenter_data(rng))
    np.testing.assert_allclose(table.theta_rad, THETAS)
    np.testing.assert_allclose(table.k_n_per_mm, KS, rtol=0.01)
    assert np.all(table.r2 > 0.99)
    assert table.notes == []
    assert table.k_range_n_per_mm[0] == pytest.approx(0.262, rel=0.01)


def test_poor_fit_warns_with_theta():
    rng = np.random.default_rng(4)
    th, d, f = indenter_data(rng)
    sel = th == 0.6
    f[sel] = 0.6 * d[sel] + rng.normal(0, 1.5, sel.sum())  # R^2 far below 0.932
    with pytest.warns(SoftnessWarning, match=r"theta_rad=0\.6: R\^2"):
        table = characterise_fabric(th, d, f)
    assert any("0.6" in n for n in table.notes)


def test_inversion_interpolates_and_is_monotonic():
    table = SoftnessTable(THETAS, KS, np.ones(5), np.full(5, 10))
    for t, k in zip(THETAS, KS, strict=True):
        assert table.theta_for(k) == pytest.approx(t)
    # Halfway between two table points in k is halfway in theta (linear interpolation).
    assert table.theta_for(0.5 * (0.41 + 0.60)) == pytest.approx(0.45)
    ks = np.linspace(0.27, 1.03, 50)
    th = [table.theta_for(k) for k in ks]
    assert np.all(np.diff(th) > 0)
    # Round trip.
    for k in ks:
        assert table.stiffness_at(table.theta_for(k)) == pytest.approx(k)


def test_non_monotonic_table_is_made_monotonic():
    ks = np.array([0.3, 0.5, 0.45, 0.8, 1.0])  # a noisy dip at theta = 0.6
    with pytest.warns(SoftnessWarning, match="not monotonic"):
        table = characterise_fabric(
            np.repeat(THETAS, 2), np.tile([1.0, 2.0], 5), np.repeat(ks, 2) * np.tile([1, 2], 5))
    assert np.all(np.diff(table.monotonic_k) >= 0)
    # The pooled points share one k (0.475); the inverse puts it at their mean theta.
    assert table.monotonic_k[1] == pytest.approx(0.475)
    assert table.theta_for(0.475) == pytest.approx(0.45)
    th = [table.theta_for(k) for k in np.linspace(0.31, 0.99, 40)]
    assert np.all(np.diff(th) > 0)


def test_decreasing_table_inverts_too():
    # A pad whose motors' sign makes k fall with theta.
    table = SoftnessTable(THETAS, KS[::-1], np.ones(5), np.ones(5))
    assert table.theta_for(1.04) == pytest.approx(0.0)
    assert table.theta_for(0.262) == pytest.approx(1.2)


def test_out_of_range_clamps_with_warning_or_refuses_when_strict():
    table = SoftnessTable(THETAS, KS, np.ones(5), np.ones(5))
    with pytest.warns(SoftnessWarning, match="outside the characterised range"):
        assert table.theta_for(2.0) == pytest.approx(1.2)
    with pytest.warns(SoftnessWarning, match=r"clamped to 0\.262"):
        assert table.theta_for(0.1) == pytest.approx(0.0)
    with pytest.raises(SoftnessError, match=r"0\.262-1\.040"):
        table.theta_for(2.0, strict=True)
    with pytest.raises(SoftnessError, match="not positive"):
        table.theta_for(-1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        table.theta_for(0.5)  # inside: no warning


def test_table_round_trips_through_csv(tmp_path):
    rng = np.random.default_rng(5)
    table = characterise_fabric(*indenter_data(rng))
    path = save_table(table, tmp_path / "t.csv", source="cal.csv")
    text = path.read_text()
    assert text.startswith("# fydpad softness table from cal.csv\n")
    assert text.splitlines()[1] == "theta_rad,k_n_per_mm,r2,n_samples"
    back = load_table(path)
    np.testing.assert_allclose(back.theta_rad, table.theta_rad, atol=1e-6)
    np.testing.assert_allclose(back.k_n_per_mm, table.k_n_per_mm, atol=1e-6)
    np.testing.assert_array_equal(back.n_samples, table.n_samples)
    assert back.theta_for(0.7) == pytest.approx(table.theta_for(0.7), abs=1e-5)


def test_bad_table_file_names_file_and_line(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("theta_rad,k_n_per_mm\n0.0,0.3\n0.5,oops\n")
    with pytest.raises(SoftnessError, match=r"bad\.csv.*line 3"):
        load_table(p)
    p.write_text("theta_rad,k_n_per_mm\n0.0,0.3\n0.5,-0.2\n")
    with pytest.raises(SoftnessError, match=r"bad\.csv.*positive"):
        load_table(p)
    with pytest.raises(SoftnessError, match="missing"):
        load_table(tmp_path / "none.csv")


def test_specimen_library_and_fit():
    assert specimen("SS1").lambda_n_per_mm == 0.88
    assert specimen("ss2").lambda_n_per_mm == 0.88
    assert specimen("SS3").lambda_n_per_mm == specimen("SS4").lambda_n_per_mm == 0.39
    assert specimen("SS2").period_mm == 2.15 and specimen("SS3").period_mm == 3.90
    with pytest.raises(SoftnessError, match="SS1, SS2, SS3, SS4"):
        specimen("SS9")
    rng = np.random.default_rng(6)
    for s in SPECIMENS.values():
        d = np.linspace(0.2, 6, 60)
        spec, fit, notes = fit_specimen(d, s.lambda_n_per_mm * d + rng.normal(0, 0.05, 60),
                                        s.name)
        assert spec.lambda_n_per_mm == pytest.approx(s.lambda_n_per_mm, rel=0.02)
        assert fit.r2 > 0.924 and notes == []


def test_specimen_poor_fit_warns():
    rng = np.random.default_rng(7)
    d = np.linspace(0.2, 6, 60)
    with pytest.warns(SoftnessWarning, match=r"below 0\.924"):
        fit_specimen(d, 0.39 * d + rng.normal(0, 0.6, 60), "noisy")


def press_stream(rng, k, depth_mm=8.0, n=200, offset_n=0.0):
    """Unloaded, ramp in, hold, ramp out, unloaded: indentation with IR-like noise and a
    load cell with noise (and an optional offset at zero load)."""
    z = np.concatenate([np.zeros(40), np.linspace(0, depth_mm, n), np.full(60, depth_mm),
                        np.linspace(depth_mm, 0, n), np.zeros(40)])
    dn = z + rng.normal(0, 0.15, z.size)
    f = k * z + rng.normal(0, 0.02, z.size) + offset_n
    return f, dn


def test_live_estimator_reports_the_press_stiffness():
    rng = np.random.default_rng(8)
    f1, d1 = press_stream(rng, 0.4)
    f2, d2 = press_stream(rng, 0.9)
    ks = stiffness_over_presses(np.concatenate([f1, f2]), np.concatenate([d1, d2]))
    assert len(ks) == 2
    assert ks[0] == pytest.approx(0.4, rel=0.03)
    assert ks[1] == pytest.approx(0.9, rel=0.03)


def test_live_estimator_ignores_unloaded_part():
    # IR noise (0.15 mm) and a load-cell offset at zero load (0.05 N): the estimate is
    # taken over the loaded part only and still gives k within a few percent; before the
    # first press there is no value at all.
    rng = np.random.default_rng(9)
    f, d = press_stream(rng, 0.6, offset_n=0.05)
    est = LiveStiffness()
    out = [est.update(float(a), float(b)) for a, b in zip(f, d, strict=True)]
    assert math.isnan(out[0])
    assert est.presses == 1 and not est.in_press
    assert est.last_k_n_per_mm == pytest.approx(0.6, rel=0.03)


def test_live_estimator_mid_press_value_and_r2():
    est = LiveStiffness()
    for z in np.linspace(0, 6, 61):
        est.update(0.5 * z, z)
    assert est.in_press
    assert est.k_n_per_mm == pytest.approx(0.5)
    assert est.r2 == pytest.approx(1.0)
    est.update(float("nan"), 3.0)  # a sensor gap changes nothing
    assert est.k_n_per_mm == pytest.approx(0.5)
