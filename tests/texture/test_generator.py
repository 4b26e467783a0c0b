"""The scan generator: determinism, hand-like speed, the paper's gratings' comb."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.texture.scan_generator import TEXTURES, generate_scan


def test_at_least_12_textures_and_paper_specimens():
    assert len(TEXTURES) >= 12
    assert TEXTURES["R1"].period_mm == 3.90 and TEXTURES["R2"].period_mm == 2.15
    assert TEXTURES["R1"].ridge_fraction == TEXTURES["R2"].ridge_fraction == 0.9


def test_deterministic_per_seed():
    a = generate_scan("cork", 20.0, 1.0, seed=4)
    b = generate_scan("cork", 20.0, 1.0, seed=4)
    c = generate_scan("cork", 20.0, 1.0, seed=5)
    np.testing.assert_array_equal(a.acc, b.acc)
    assert not np.allclose(a.acc, c.acc)


def test_a_variant_of_a_texture_gets_its_own_surface():
    """A texture changed in one field but keeping its name (how a study takes a texture's
    processes apart) is scanned over its own profile, whichever was generated first."""
    import dataclasses

    smooth = dataclasses.replace(TEXTURES["brick"], rough_mm=0.0, pits_per_mm=0.0)
    for first in (smooth, TEXTURES["brick"]):
        a = generate_scan(first, 20.0, 2.0, seed=3)
        other = smooth if first is TEXTURES["brick"] else TEXTURES["brick"]
        b = generate_scan(other, 20.0, 2.0, seed=3)
        # The same hand and noise draws; a flat surface gives a far weaker vertical signal.
        ratio = np.std(np.diff(b.acc[:, 2])) / np.std(np.diff(a.acc[:, 2]))
        assert (ratio < 0.5) if other is smooth else (ratio > 2.0), ratio
    # Its friction's ground truth follows its own profile's slopes too.
    from fydpad.texture.scan_generator import friction_truth

    assert not np.allclose(friction_truth(smooth)[0], friction_truth("brick")[0])


def test_speed_varies_like_a_hand_and_gravity_is_there():
    s = generate_scan("felt", 20.0, 6.0, seed=1)
    mid = s.speed_mm_s[1000:-1000]
    assert 0.5 < np.std(mid) < 5.0  # wanders, mostly within the paper's 5 mm/s
    assert np.mean(np.abs(mid - 20.0) <= 5.0) > 0.8
    assert s.speed_mm_s[0] < 2.0  # a stroke starts from rest
    assert np.mean(s.acc[:, 2]) == pytest.approx(9.81, abs=0.3)


@pytest.mark.parametrize(("name", "speed"), [("R1", 40.0), ("R1", 30.0), ("R2", 40.0)])
def test_grating_comb_spacing_and_every_tenth_harmonic_vanishes(name, speed):
    """Normal axis at constant speed: lines at n*speed/period, the 10th ones missing."""
    s = generate_scan(name, speed, 12.0, seed=3, hand_variation=0.0)
    z = s.acc[1000:-1000, 2]
    f, p = ss.periodogram(z - z.mean(), 1000.0, window="hann")
    f0 = speed / TEXTURES[name].period_mm
    df = f[1] - f[0]
    floor = np.median(p[(f > 20) & (f < 480)])

    def line(k: int) -> float:
        return float(p[(f > k * f0 - 2 * df) & (f < k * f0 + 2 * df)].max())

    ks = [k for k in range(1, 40) if 20 <= k * f0 <= 480]
    strong = [k for k in ks if k % 10 and line(k) > 100 * floor]
    # The comb's spacing in band: consecutive harmonics (not one peak) stand out.
    assert len(strong) >= 6
    assert np.all(np.diff(strong)[: 5] <= 2)
    checked = 0
    for k in (10, 20):
        if k + 1 in strong and k - 1 in strong:
            assert line(k) < 0.1 * np.sqrt(line(k - 1) * line(k + 1)), k
            checked += 1
    assert checked >= 1
