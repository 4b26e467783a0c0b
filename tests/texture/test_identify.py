"""The identification's distance (third-octave band levels) and its determinism.

The pieces are checked against values computed by hand; identification on real-material
models is measured by benchmarks/hatt_corpus.py.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.evaluation.identify import (
    band_level_distance_db,
    band_levels_db,
    identify_families,
)
from fydpad.texture.lpc.family import LpcFamily
from fydpad.texture.lpc.fit import fit_texture

F_HZ = np.arange(0.0, 501.0, 4.0)  # the Welch grid of evaluate (4 Hz bins, fs 1 kHz)


def test_band_levels_of_a_flat_spectrum():
    """14 third-octave bands over 20-500 Hz (edges 20 * 2^(k/3)), each at the flat level."""
    levels = band_levels_db(F_HZ, np.full(F_HZ.size, 1e-3))
    assert levels.shape == (14,)
    np.testing.assert_allclose(levels, -30.0, atol=1e-9)


def test_band_level_is_the_mean_power_of_its_bins():
    """One bin at 100 Hz carries 1.0, the rest 1e-9: its band (100.8-127 Hz holds
    104..124, so 100 Hz falls in 80-100.8: bins 80..100, six of them) reads 1/6."""
    p = np.full(F_HZ.size, 1e-9)
    p[F_HZ == 100.0] = 1.0
    levels = band_levels_db(F_HZ, p)
    k = int(np.argmax(levels))
    assert levels[k] == pytest.approx(10 * np.log10((1.0 + 5e-9) / 6), abs=1e-9)
    assert k == 6  # 20, 25.2, 31.7, 40, 50.4, 63.5, [80-100.8]


def test_band_distance_weighs_octaves_not_hertz():
    """A 10 dB error over the octave 20-40 Hz (5 bins, 3 bands) and over 160-320 Hz
    (40 bins, 3 bands) cost the same band distance, 10 * sqrt(3/14) dB; on 4 Hz bins
    the second would cost sqrt(8) times the first."""
    ref = np.full(F_HZ.size, 1e-3)
    low, high = ref.copy(), ref.copy()
    low[(F_HZ >= 20) & (F_HZ < 40)] *= 10.0
    high[(F_HZ >= 160) & (F_HZ < 320)] *= 10.0
    expected = 10.0 * np.sqrt(3 / 14)
    assert band_level_distance_db(F_HZ, ref, low) == pytest.approx(expected, rel=1e-9)
    assert band_level_distance_db(F_HZ, ref, high) == pytest.approx(expected, rel=1e-9)
    assert band_level_distance_db(F_HZ, ref, 2 * ref) == pytest.approx(10 * np.log10(2))


def test_identify_does_not_depend_on_the_order_of_the_scans():
    """Each scan's synthesis starts from the seed (the renderer's pre-drawn noise is
    dropped), so its distances are the same whichever scans came before it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = [LpcFamily(fit_texture([generate_scan(n, s, 3.0, seed=1) for s in (10.0, 20.0)],
                                        speeds_mm_s=(10.0, 20.0))) for n in ("R1", "felt")]
        scans = [generate_scan(n, 15.0, 3.0, seed=7) for n in ("R1", "felt")]
        labels = [m.surface for m in models]
        a = identify_families(models, labels, scans, distance="bands")
        b = identify_families(models, labels, scans[::-1], distance="bands")
    assert a.assignments[0]["distance_db"] == b.assignments[1]["distance_db"]
    assert a.assignments[1]["distance_db"] == b.assignments[0]["distance_db"]
    assert a.assignments[0]["distance"] == "bands"
    with pytest.raises(ValueError, match="distance"):
        identify_families(models, labels, scans, distance="cosine")
