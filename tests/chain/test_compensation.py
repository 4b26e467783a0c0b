"""Compensation on the simulated plant: the reproduced spectrum within
3 dB of the target over the coherent band, where no compensation (gain only) misses by
10 dB or more at the resonance. Absolute spectra in m/s^2, no fitted scale."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.chain.check import band_target, check_compensation, scan_target
from tests.chain.conftest import BAND_HZ

SECONDS = 20.0


def test_band_target_within_3_db_uncompensated_misses_10_db(chain_at):
    s, entry = chain_at(0.6)
    target = band_target(int(SECONDS * s.rate_hz), s.rate_hz, BAND_HZ, seed=5)
    res = check_compensation(s, entry, BAND_HZ, target)
    fig = res.figures
    assert fig["vibration_clips"] == 0
    assert fig["compared_bins"] >= 150  # most of the 10-450 Hz band (1.95 Hz bins)
    assert fig["compensated_max_error_db"] <= 3.0, fig
    assert fig["offline_max_error_db"] <= 3.0, fig
    assert fig["uncompensated_error_at_resonance_db"] >= 10.0, fig


def test_texture_scan_within_3_db(chain_at):
    # wood_grain as the pad's scans record it (DFT321, 10 Hz high-pass): a texture's
    # spectrum with 40 dB of range; compared where it is within 25 dB of its peak.
    s, entry = chain_at(0.6)
    target = scan_target("wood_grain", 30.0, SECONDS, s.rate_hz, seed=1)
    res = check_compensation(s, entry, BAND_HZ, target, offline=False)
    fig = res.figures
    assert fig["compared_bins"] >= 60
    assert fig["compensated_max_error_db"] <= 3.0, fig
    assert fig["uncompensated_error_at_resonance_db"] >= 10.0, fig


# With the fabric's damping 0.12 the peak is ~12.6 dB over the low plateau, and the median
# gain it is referred to rises as the resonance nears the band's top.
@pytest.mark.xfail(strict=True, reason="k = 1.0 N/mm: gain-only misses by 9.4 dB, not 10, at "
                   "the ~290 Hz resonance (docs/chain.md)")
def test_uncompensated_misses_10_db_at_high_stiffness(chain_at):
    s, entry = chain_at(1.0)
    target = band_target(int(SECONDS * s.rate_hz), s.rate_hz, BAND_HZ, seed=5)
    res = check_compensation(s, entry, BAND_HZ, target, offline=False)
    assert res.figures["uncompensated_error_at_resonance_db"] >= 10.0, res.figures


def test_compensated_drive_reshapes_as_the_inverse(chain_at):
    # The compensated drive's spectrum is the target's over |TF| (eq. 3: Z = FIV / TF).
    from scipy import signal

    from fydpad.chain.inverse_filter import fir_filter
    from fydpad.chain.live import design_inverse

    s, entry = chain_at(0.6)
    est = entry.estimate
    target = band_target(20000, s.rate_hz, BAND_HZ, seed=3)
    z, _ = fir_filter(design_inverse(est, s.rate_hz, BAND_HZ), target)
    f, pz = signal.welch(z, s.rate_hz, nperseg=512)
    _, pt = signal.welch(target, s.rate_hz, nperseg=512)
    good = est.coherent(BAND_HZ) & (f > 20) & (f < 400)
    ratio_db = 10 * np.log10(pz[good] / pt[good]) + 20 * np.log10(np.abs(est.tf[good]))
    assert np.max(np.abs(ratio_db)) < 1.0
