"""Speed from centroid differentiation and the paper's 10 Hz low-pass."""

from __future__ import annotations

import numpy as np
import pytest

from vision.speed import SpeedState, speed_update


def run(t, x, y, contact):
    state = SpeedState()
    out = []
    for args in zip(t, x, y, contact, strict=True):
        s, state = speed_update(state, *args)
        out.append(s)
    return np.array(out)


def test_constant_velocity_converges_to_the_true_speed():
    t = np.arange(90) / 30.0
    x, y = 30.0 * t - 40, -40.0 * t + 20  # 50 mm/s
    s = run(t, x, y, [True] * 90)
    assert s[0] == 0.0
    assert s[-30:] == pytest.approx(50.0, rel=1e-9)


def test_low_pass_time_constant_is_10_hz():
    t = np.arange(300) / 1000.0
    s = run(t, 20.0 * t, 0 * t, [True] * 300)
    # First-order low-pass at 10 Hz: 63 % of the step after tau = 1 / (2 pi 10) s = 15.9 ms.
    k = int(np.searchsorted(s, 0.632 * 20.0))
    assert t[k] - t[1] == pytest.approx(1 / (2 * np.pi * 10), abs=0.0015)


def test_contact_loss_resets_and_no_jump_on_touch_elsewhere():
    t = np.arange(6) / 30.0
    x = [0, 1, np.nan, 40, 41, 42]
    c = [True, True, False, True, True, True]
    s = run(t, x, [0] * 6, c)
    assert s[2] == 0.0 and s[3] == 0.0  # landing 40 mm away is not a 1200 mm/s stroke
    assert 0 < s[5] < 30.0


def test_irregular_intervals_and_repeated_time():
    s, st = speed_update(SpeedState(), 0.0, 0.0, 0.0, True)
    s, st = speed_update(st, 0.1, 1.0, 0.0, True)
    s2, st2 = speed_update(st, 0.1, 5.0, 0.0, True)  # same time stamp: ignored
    assert s2 == s and st2 == st
