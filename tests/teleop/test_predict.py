"""The slave's extrapolator (predict.py)."""

from __future__ import annotations

import numpy as np
import pytest

from teleop.predict import Predictor


def test_quadratic_motion_is_extrapolated_exactly():
    """A constant-acceleration path (a tap's turn) is predicted without error."""
    p = Predictor(window=6, degree=2, max_horizon_s=0.1)
    f = lambda t: np.array([3.0 + 40 * t - 800 * t * t])  # noqa: E731
    for k in range(6):
        p.add(k / 30, f(k / 30))
    t = 5 / 30 + 0.04
    assert p.predict_flat(t)[0] == pytest.approx(f(t)[0], abs=1e-9)


def test_short_history_uses_lower_degree():
    p = Predictor(6, 2)
    assert p.predict(1.0) is None
    p.add(0.0, np.array([1.0]))
    assert p.predict_flat(0.5)[0] == 1.0  # one sample: hold
    p.add(0.1, np.array([2.0]))
    assert p.predict_flat(0.15)[0] == pytest.approx(2.5)  # two: the line


def test_horizon_is_capped():
    """A stale history does not fly off: extrapolation stops at max_horizon_s."""
    p = Predictor(4, 1, max_horizon_s=0.05)
    p.add(0.0, np.array([0.0]))
    p.add(0.1, np.array([10.0]))
    assert p.predict_flat(5.0)[0] == pytest.approx(15.0)


def test_times_must_increase():
    p = Predictor()
    p.add(1.0, np.zeros(3))
    with pytest.raises(ValueError, match="not after"):
        p.add(1.0, np.zeros(3))


def test_noise_is_not_amplified_much():
    """With 0.1 mm noise on a still finger the prediction error stays near the noise."""
    rng = np.random.default_rng(1)
    p = Predictor(6, 2, 0.12)
    errs = []
    for k in range(300):
        p.add(k / 30, rng.normal(0, 0.1, 1))
        if k > 6:
            errs.append(abs(p.predict_flat(k / 30 + 1 / 30)[0]))
    assert np.mean(errs) < 0.35
