"""Speed from centroid differentiation and the paper's 10 Hz low-pass."""

from __future__ import annotations

import numpy as np
import pytest

from vision.speed import CentroidSpeed, SpeedState, speed_update


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


def test_centroid_speed_at_1khz_from_30hz_positions():
    cs = CentroidSpeed()
    speeds = []
    for k in range(2000):  # 2 s at 1 kHz, camera every 33 ticks, finger at 20 mm/s
        t = k / 1000.0
        if k % 33 == 0:
            cs.position(t, 20.0 * t, 0.0, True)
        speeds.append(cs.tick(1e-3))
    assert speeds[-1] == pytest.approx(20.0, rel=0.02)
    assert max(np.abs(np.diff(speeds[500:]))) < 0.5  # smooth, not a 30 Hz staircase
    cs.position(2.0, 40.0, 0.0, False)
    assert cs.tick() == 0.0


def _sampled_speeds(x_of_t, fps: float, seconds: float, step_mm: float = 0.0) -> np.ndarray:
    """CentroidSpeed.sample at 1 kHz with the newest camera centroid held between frames
    (quantised to ``step_mm`` when given, as a tracker's pixels are)."""
    cs = CentroidSpeed()
    out = np.empty(int(seconds * 1000))
    for k in range(out.size):
        t = k / 1000.0
        x = x_of_t(np.floor(t * fps) / fps)
        if step_mm:
            x = step_mm * np.round(x / step_mm)
        cs.sample(t, x, 0.0, True)
        out[k] = cs.tick(1e-3)
    return out


@pytest.mark.parametrize("fps", [10.0, 30.0])
def test_sample_rests_a_still_finger_and_starts_without_overshoot(fps):
    """Still for 1.2 s, then 20 mm/s: silent while still, and no overshoot at the start
    (re-basing the time at rest once divided the first step by too short a time: 39.9
    mm/s at 10 frames/s). A finger creeping at 0.3 mm/s on a 0.1 mm-quantised tracker
    stays below the 1 mm/s still threshold (it read 1.2 mm/s)."""
    v = _sampled_speeds(lambda t: 20.0 * max(t - 1.2, 0.0), fps, 3.0)
    assert np.all(v[300:1200] == 0.0)
    assert v.max() < 20.0 * 1.05 and v[-1] == pytest.approx(20.0, rel=0.02)
    creep = _sampled_speeds(lambda t: 0.3 * t, fps, 6.0, step_mm=0.1)
    assert creep[1000:].max() < 1.0
