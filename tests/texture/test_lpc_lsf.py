"""LPC estimation, stability and the LSF conversions (the HaTT import's)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.texture.lpc.analysis import (
    is_stable,
    levinson,
    lpc_autocorrelation,
    poly_to_reflection,
    reflection_to_poly,
)
from fydpad.texture.lpc.lsf import lsf_to_poly, poly_to_lsf

TRUE_A = np.array([1.0, -1.6, 1.5, -0.7, 0.2])


@pytest.fixture(scope="module")
def ar_signal() -> np.ndarray:
    rng = np.random.default_rng(0)
    return ss.lfilter([1.0], TRUE_A, rng.normal(0, 0.1, 200_000))


def test_levinson_recovers_known_ar(ar_signal):
    a, s2 = lpc_autocorrelation([ar_signal], 4)
    np.testing.assert_allclose(a, TRUE_A, atol=0.01)
    assert s2 == pytest.approx(0.01, rel=0.02)


def test_pooled_segments_equal_one_long_segment_closely(ar_signal):
    a1, _ = lpc_autocorrelation([ar_signal], 4)
    a2, _ = lpc_autocorrelation(np.array_split(ar_signal, 10), 4)
    np.testing.assert_allclose(a1, a2, atol=5e-3)


def test_order_200_fit_is_stable(ar_signal):
    a, _ = lpc_autocorrelation([ar_signal[:10_000]], 200)
    assert is_stable(a)
    assert np.max(np.abs(np.roots(a))) < 1.0  # every pole inside the unit circle


def test_stability_check_detects_unstable():
    assert not is_stable([1.0, -2.1, 1.1])  # a pole at 1.1
    assert is_stable([1.0, -0.5])
    k = poly_to_reflection(TRUE_A)
    np.testing.assert_allclose(reflection_to_poly(k), TRUE_A, atol=1e-12)
    _, _, k2 = levinson(np.array([1.0, 0.5, 0.2]), 2)
    assert np.all(np.abs(k2) < 1)


def test_lsf_round_trip_order_200(ar_signal):
    a, _ = lpc_autocorrelation([ar_signal[:20_000]], 200)
    lsf = poly_to_lsf(a)
    assert lsf.size == 200 and np.all(np.diff(lsf) > 0) and 0 < lsf[0] and lsf[-1] < np.pi
    np.testing.assert_allclose(lsf_to_poly(lsf), a, atol=1e-9)
