"""Load cell: counts to newtons, saturation, calibration from known weights."""

from __future__ import annotations

import numpy as np
import pytest

from vision.config import G_M_S2, ForceConfig
from vision.force import ForceCalibrationError, calibrate_force, raw_to_force


def test_counts_to_newtons_with_offset_and_gain():
    cfg = ForceConfig(offset_counts=1000.0, gain_n_per_count=2e-5)
    r = raw_to_force([1000, 51000, 0], cfg)
    np.testing.assert_allclose(r.force_n, [0.0, 1.0, -0.02])
    assert not r.saturated.any()


def test_full_scale_is_780_g_and_saturates():
    cfg = ForceConfig(offset_counts=0.0, gain_n_per_count=1e-3)
    assert cfg.full_scale_n == pytest.approx(7.6492, abs=1e-4)
    r = raw_to_force([7000, 7649, 7650, 9000, -8000], cfg)
    assert list(r.saturated) == [False, False, True, True, True]
    # At the ADC's rails the number is meaningless whatever the gain says.
    small = ForceConfig(gain_n_per_count=1e-9)
    assert list(raw_to_force([2**23 - 1, -(2**23), 0], small).saturated) == [True, True, False]


def test_calibration_recovers_offset_and_gain_from_noisy_weights():
    rng = np.random.default_rng(0)
    masses = np.repeat([0.0, 50.0, 100.0, 200.0, 500.0, 700.0], 5)
    gain, offset = 3.6e-6, -12000.0
    raw = offset + masses * 1e-3 * G_M_S2 / gain + rng.normal(0, 40, masses.size)
    cal = calibrate_force(masses, raw)
    assert cal.gain_n_per_count == pytest.approx(gain, rel=2e-3)
    assert cal.offset_counts == pytest.approx(offset, abs=60)
    assert cal.r2 > 0.9999
    assert cal.rms_residual_n == pytest.approx(40 * gain, rel=0.4)
    cfg = cal.config()
    np.testing.assert_allclose(raw_to_force(raw, cfg).force_n, masses * 1e-3 * G_M_S2,
                               atol=6 * 40 * gain)


@pytest.mark.parametrize(("masses", "raw", "match"), [
    ([0, 100], [0, 1000], "at least 3"),
    ([100, 100, 100], [0, 10, 20], "two different weights"),
    ([0, 100, 200], [5, 5, 5], "do not change"),
    ([0, 100, 900], [0, 1, 2], "full scale"),
])
def test_calibration_refuses_degenerate_data(masses, raw, match):
    with pytest.raises(ForceCalibrationError, match=match):
        calibrate_force(masses, raw)


def test_config_validation():
    with pytest.raises(ValueError, match="gain"):
        ForceConfig(gain_n_per_count=0.0)
