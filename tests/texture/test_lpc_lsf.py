"""LPC estimation, stability and the LSF conversions (the HaTT import's)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.texture.lpc.analysis import is_stable, lpc_autocorrelation
from fydpad.texture.lpc.lsf import lsf_to_poly
from tests.texture.lpc_polys import poly_to_lsf, reflection_to_poly

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
    assert not is_stable(reflection_to_poly([0.5, -1.0, 0.2]))  # |k_2| = 1: on the circle
    assert is_stable(reflection_to_poly([0.5, -0.99, 0.2]))


def test_lsf_to_poly_inverts_the_lsfs():
    """Odd and even order, against LSFs found from the polynomial's roots."""
    for a in (TRUE_A, reflection_to_poly([0.5, -0.3, 0.2])):
        np.testing.assert_allclose(lsf_to_poly(poly_to_lsf(a)), a, atol=1e-12)


def test_sorted_lsfs_at_order_200_are_a_stable_filter():
    jitter = np.random.default_rng(0).uniform(-0.4, 0.4, 200)
    lsf = np.pi * (np.arange(1, 201) + jitter) / 201  # sorted, interlaced
    assert is_stable(lsf_to_poly(lsf))
