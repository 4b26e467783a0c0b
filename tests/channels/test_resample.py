import numpy as np
import pytest
from scipy.signal import resample_poly, upfirdn

from fydpad.channels.resample import Resampler, ratio


@pytest.mark.parametrize("fout", [48000, 44100, 250])
def test_blockwise_equals_oneshot_and_upfirdn(fout):
    rng = np.random.default_rng(1)
    x = rng.standard_normal(3000)
    one = Resampler(1000, fout).process(x)  # the whole signal at once
    r = Resampler(1000, fout)
    cuts = np.sort(rng.integers(0, len(x), 12))
    blocks = [r.process(b) for b in np.split(x, cuts)]
    y = np.concatenate(blocks)
    assert len(y) == len(one)
    np.testing.assert_allclose(y, one, atol=1e-12, rtol=0)
    ref = upfirdn(r.h, x, r.up, r.down)[: len(y)]
    np.testing.assert_allclose(y, ref, atol=1e-12, rtol=0)


@pytest.mark.parametrize("fout", [48000, 44100])
def test_matches_resample_poly_away_from_edges(fout):
    x = np.random.default_rng(2).standard_normal(2000)
    r = Resampler(1000, fout)
    half_len = (len(r.h) - 1) // 2
    assert half_len % r.down == 0
    shift = half_len // r.down
    y = r.process(x)
    rp = resample_poly(x, r.up, r.down)
    edge = len(r.h)
    np.testing.assert_allclose(y[shift + edge: len(rp) - edge + shift],
                               rp[edge: len(rp) - edge], atol=1e-12)


def test_ratio():
    assert ratio(1000, 44100) == (441, 10)
    assert ratio(1000, 48000) == (48, 1)
