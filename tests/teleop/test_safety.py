"""Slave safety: box, speed and acceleration limits, watchdog."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleop.config import SafetyConfig
from teleop.protocol import Sample
from teleop.safety import MotionLimiter, Watchdog


def smp(seq, t, x=0.0, contact=True, force=1.0):
    return Sample(seq, t, t, x, 0.0, 1.0, force, contact)


def run_limiter(lim, targets, dt):
    out = [lim.cmd_mm.copy()]
    for tgt in targets:
        out.append(lim.step(np.asarray(tgt, float), dt))
    return np.array(out)


def test_box_clamps_targets():
    cfg = SafetyConfig(box_min_mm=(0, 0, 0), box_max_mm=(10, 10, 10))
    lim = MotionLimiter(cfg, np.array([5.0, 5.0, 5.0]))
    out = run_limiter(lim, [[50.0, -50.0, 5.0]] * 2000, 0.002)
    np.testing.assert_allclose(out[-1], [10.0, 0.0, 5.0], atol=1e-6)
    assert out[:, 0].max() <= 10.0 and out[:, 1].min() >= 0.0


def test_a_jump_is_limited_in_speed_and_acceleration_and_does_not_overshoot():
    cfg = SafetyConfig(box_min_mm=(-1e3,) * 3, box_max_mm=(1e3,) * 3)
    dt = 0.002
    lim = MotionLimiter(cfg, np.zeros(3))
    out = run_limiter(lim, [[100.0, 0.0, 0.0]] * 1000, dt)
    v = np.diff(out[:, 0]) / dt
    a = np.diff(v) / dt
    assert v.max() <= cfg.max_speed_mm_s + 1e-6
    assert np.abs(a).max() <= cfg.max_accel_mm_s2 * (1 + 1e-6)
    assert out[:, 0].max() <= 100.0 + 0.01  # discrete braking: at most 0.01 mm past
    assert out[-1, 0] == pytest.approx(100.0, abs=1e-6)


def test_a_100_mm_s_tap_passes_the_default_limits():
    """A tap at 100 mm/s peak (sin^2 press, 8 mm deep) is followed within 0.05 mm."""
    cfg = SafetyConfig(box_min_mm=(-1e3,) * 3, box_max_mm=(1e3,) * 3)
    dt = 0.002
    press = 0.3
    depth = 100.0 * press / math.pi
    t = np.arange(0, 1.0, dt)
    z = np.where(np.mod(t, 0.5) < press, depth * np.sin(math.pi * np.mod(t, 0.5) / press) ** 2, 0)
    lim = MotionLimiter(cfg, np.zeros(3))
    out = run_limiter(lim, [[0.0, 0.0, zi] for zi in z], dt)
    assert np.abs(out[1:, 2] - z).max() < 0.05


def test_hold_decelerates_within_limits_then_stays():
    cfg = SafetyConfig(box_min_mm=(-1e3,) * 3, box_max_mm=(1e3,) * 3)
    dt = 0.002
    lim = MotionLimiter(cfg, np.zeros(3))
    run_limiter(lim, [[k * 0.4, 0, 0] for k in range(1, 200)], dt)  # 200 mm/s
    x = [lim.hold(dt)[0] for _ in range(100)]
    v = np.diff(x) / dt
    assert np.abs(np.diff(v) / dt).max() <= cfg.max_accel_mm_s2 * (1 + 1e-6)
    assert v[-1] == pytest.approx(0.0, abs=1e-9)


def test_watchdog():
    w = Watchdog(0.25)
    assert not w.alive(0.0)
    w.feed(1.0)
    assert w.alive(1.2)
    assert not w.alive(1.26)
    assert w.trips == 1


def test_an_axis_past_its_target_keeps_its_share_of_braking():
    """x brakes hard onto a target 3 mm ahead at 290 mm/s while the depth, at its target,
    still moves deeper at 100 mm/s. The depth must get its share of the deceleration: with
    the whole budget it would stop 0.5 mm deeper (v^2 / 2a), with a proportional share
    0.74 mm; with none while x brakes (the review found this) 2.1 mm."""
    cfg = SafetyConfig(box_min_mm=(-1e3,) * 3, box_max_mm=(1e3,) * 3)
    lim = MotionLimiter(cfg, np.zeros(3))
    lim.step(np.array([3.0, 0.0, 0.0]), 0.002)  # the target holds still from here on
    lim.cmd_mm = np.zeros(3)
    lim.vel_mm_s = np.array([290.0, 0.0, -100.0])
    out = run_limiter(lim, [[3.0, 0.0, 0.0]] * 100, 0.002)
    assert out[:, 2].min() >= -1.0
    assert out[-1] == pytest.approx([3.0, 0.0, 0.0], abs=0.05)


def test_an_axis_brakes_onto_its_target_while_another_swings():
    """A re-engage 5 mm away in x while the depth target swings by 8 mm at the frame rate
    (a touch-down's prediction): x lands without passing its target and the acceleration
    vector stays within the limit. Scaling the whole velocity change to the limit let the
    depth take the budget x needed to brake (x overshot by 0.6 mm)."""
    cfg = SafetyConfig(box_min_mm=(-1e3,) * 3, box_max_mm=(1e3,) * 3)
    dt = 0.002
    lim = MotionLimiter(cfg, np.zeros(3))
    targets = [[5.0, 0.0, -8.0 if (k // 17) % 2 == 0 else 0.0] for k in range(300)]
    out = run_limiter(lim, targets, dt)
    v = np.diff(out, axis=0) / dt
    a = np.linalg.norm(np.diff(v, axis=0), axis=1) / dt
    assert a.max() <= cfg.max_accel_mm_s2 * (1 + 1e-6)
    assert np.linalg.norm(v, axis=1).max() <= cfg.max_speed_mm_s + 1e-6
    assert out[:, 0].max() <= 5.0 + 0.01
    assert out[-1, 0] == pytest.approx(5.0, abs=0.01)
