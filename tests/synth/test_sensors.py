"""IR voltages and load cell against the truth: eq. (1) inverted, ADC, the plane's error."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.synth import SynthConfig, SyntheticPad
from fydpad.synth.sensors import ForceParams
from vision.indentation import IndentationEstimator, indentation_at_frames, rmse
from vision.ir import VALID_VOLTAGE_RANGE_V, distance_to_voltage_v


@pytest.fixture(scope="module")
def tapping() -> SyntheticPad:
    return SyntheticPad(SynthConfig(trajectory="tapping", seconds=12.0, seed=17))


def test_ir_is_sampled_at_100_hz_on_a_10_bit_5_v_adc(tapping):
    t, v = tapping.ir()
    assert t.size == 1200 and v.shape == (1200, 3)
    np.testing.assert_allclose(np.diff(t), 0.01)
    codes = v / (5.0 / 1024)
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-9)
    assert np.all((v >= VALID_VOLTAGE_RANGE_V[0]) & (v <= VALID_VOLTAGE_RANGE_V[1]))


def test_ir_at_rest_reads_each_sensors_own_distance(tapping):
    t, v = tapping.ir()
    rest = t < 0.7
    expected = distance_to_voltage_v(tapping.ir_rest_mm)
    np.testing.assert_allclose(v[rest].mean(axis=0), expected, atol=0.004)
    # Noise of a few ADC steps, and the sensors differ from one another (mounting).
    assert 0.0 < v[rest].std(axis=0).max() < 0.02
    assert np.ptp(tapping.ir_rest_mm) > 0.1


def test_the_plane_estimate_errs_like_the_papers_on_a_non_planar_fabric(tapping):
    """Eq. (1) + eq. (2) at the true centroids, rest distances from no-contact samples:
    a few mm RMS over 0-50 mm (paper: 2.88 mm) -- not zero, not 20 mm."""
    t, v = tapping.ir()
    x, y, z = tapping.path.at(t)
    c = z > 0
    res, est = indentation_at_frames(IndentationEstimator(), t, v, t, c,
                                     np.where(c, x, np.nan), np.where(c, y, np.nan))
    np.testing.assert_allclose(est.baseline_mm, tapping.ir_rest_mm, atol=0.6)
    assert z.max() > 35.0
    err = rmse(res.indentation_mm[c], z[c])
    assert 1.5 < err < 4.5
    # Shallow presses are measured well; the error is the fabric's shape at depth.
    shallow = c & (z < 5.0)
    assert rmse(res.indentation_mm[shallow], z[shallow]) < 1.0


def test_ir_follows_the_fabric_not_the_finger_above_it():
    pad = SyntheticPad(SynthConfig(trajectory="hover", seconds=6.0, seed=2))
    t, v = pad.ir()
    _, _, z = pad.path.at(t)
    above = (z < 0) & (t > 0.05)
    assert np.ptp(v[above], axis=0).max() < 0.05  # noise only: the fabric is flat


def test_load_cell_is_k_times_delta_and_saturates_at_780_g():
    walk = SyntheticPad(SynthConfig(trajectory="walk", seconds=12.0, seed=5))
    fabric, theta = walk.cfg.fabric, walk.cfg.force.theta_rad
    k = fabric.stiffness_at_theta(theta)
    assert 0.261 <= k <= 1.04  # the paper's 0.262-1.04 N/mm (0.2613 at the rest position)
    tension = fabric.tension_n(fabric.stretch_mm(theta, theta))
    t, f = walk.force()
    d = walk.path.indentation_mm(t)
    rate = np.gradient(d, t)
    # Held presses: the static law F = k delta (+ the dent's stiffening), noise only.
    held = (d > 1.0) & (np.abs(rate) < 0.5)
    assert held.sum() > 10
    np.testing.assert_allclose(f[held], fabric.force_n(d[held], tension), atol=0.05)
    assert np.all(f[held] >= k * d[held] - 0.05)
    np.testing.assert_allclose(f[d == 0].mean(), 0.0, atol=0.01)
    # Moving: the fabric's damping makes pressing harder than releasing at one depth.
    tap = SyntheticPad(SynthConfig(trajectory="tapping", seconds=12.0, seed=17))
    t, f = tap.force()
    d = tap.path.indentation_mm(t)
    rate = np.gradient(d, t)
    mid = (d > 8.0) & (d < 12.0)
    assert f[mid & (rate > 20)].mean() > f[mid & (rate < -20)].mean() + 0.1
    # Deep taps on a stiffer fabric go past the cell's 780 g: it reads full scale.
    stiff = SyntheticPad(SynthConfig(trajectory="tapping", seconds=12.0, seed=17,
                                     force=ForceParams(theta_rad=1.2)))
    _, f_stiff = stiff.force()
    assert f_stiff.max() == pytest.approx(0.780 * 9.80665)
    assert np.sum(f_stiff == f_stiff.max()) > 10
