"""The report's figures as docs/recording_format.md defines them (eq. 6), on hand-made logs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from teleop.config import SafetyConfig
from teleop.report import best_lag_s, interp_log, latency_ms, mae_per_axis
from teleop.safety import MotionLimiter


def test_mae_starts_at_first_contact_interpolates_the_slave_and_skips_missing_axes():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    contact = np.array([False, True, True, False])
    master = np.array([[np.nan, np.nan, 0.0], [1.0, 2.0, 3.0], [2.0, 2.0, 3.0],
                       [np.nan, np.nan, 0.0]])
    # Slave log at other instants: linear in time, so interpolation is exact.
    tl = np.array([0.0, 0.05, 0.15, 0.25, 0.35])
    sl = np.column_stack([10 * tl, np.full(5, 2.5), np.full(5, 1.0)])
    mae = mae_per_axis(t, master, contact, tl, sl)
    # x: |1 - 1| and |2 - 2| -> 0; y: 0.5 twice; z: |3-1|, |3-1|, |0-1| over 3 samples.
    np.testing.assert_allclose(mae, [0.0, 0.5, 5.0 / 3.0])


def test_slave_log_outside_its_span_is_not_extrapolated():
    out = interp_log(np.array([-1.0, 0.5, 2.0]), np.array([0.0, 1.0]), np.ones((2, 3)))
    assert np.isnan(out[0]).all() and np.isnan(out[2]).all() and (out[1] == 1).all()


def test_lag_finds_the_delay_and_mae_applies_none():
    t = np.arange(0, 4, 1 / 30)
    master = np.column_stack([20 * np.sin(2 * t), 10 * np.cos(3 * t), np.full(t.size, 2.0)])
    tl = np.arange(-0.5, 4.5, 0.002)
    delayed = np.column_stack([20 * np.sin(2 * (tl - 0.05)), 10 * np.cos(3 * (tl - 0.05)),
                               np.full(tl.size, 2.0)])
    contact = np.ones(t.size, bool)
    assert best_lag_s(t, master, contact, tl, delayed) == pytest.approx(0.05, abs=0.0011)
    assert mae_per_axis(t, master, contact, tl, delayed)[0] > 0.5  # the delay is an error


def test_latency_percentiles_in_ms():
    assert latency_ms(np.array([0.001] * 99 + [0.010])) == {"p50": 1.0, "p99": 1.09}
    assert latency_ms(np.array([])) == {"p50": None, "p99": None}


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-500, 500), st.floats(-500, 500), st.floats(-500, 500)),
                min_size=1, max_size=40),
       st.integers(1, 50))
def test_limiter_never_breaks_its_limits(targets, hold_ticks):
    """Whatever the targets (jumps, out of the box), the command stays in the box and its
    speed and acceleration within the limits."""
    cfg = SafetyConfig(box_min_mm=(-100, -100, -100), box_max_mm=(100, 100, 100))
    dt = 0.002
    lim = MotionLimiter(cfg, np.zeros(3))
    cmds = [lim.cmd_mm.copy()]
    for tgt in targets:
        for _ in range(hold_ticks):
            cmds.append(lim.step(np.array(tgt), dt))
    c = np.array(cmds)
    assert (c >= -100 - 1e-9).all() and (c <= 100 + 1e-9).all()
    v = np.diff(c, axis=0) / dt
    assert np.linalg.norm(v, axis=1).max() <= cfg.max_speed_mm_s * (1 + 1e-9)
    a = np.diff(v, axis=0) / dt
    # Clamping to the box can stop the command harder than the limit (a wall), so the
    # acceleration bound is checked where the box did not act.
    inside = (np.abs(c[1:-1]) < 100 - 1e-6).all(axis=1) & (np.abs(c[2:]) < 100 - 1e-6).all(axis=1)
    assert (np.linalg.norm(a[inside], axis=1) <= cfg.max_accel_mm_s2 * (1 + 1e-6)).all()


def test_truth_breakdown_separates_sensing_from_the_link_per_axis():
    """Master off the truth by 0.3 mm in x and 2 mm in z, the slave off the master by
    0.1 mm in y: each part lands where it belongs and the end to end adds them."""
    from teleop.report import breakdown_lines, truth_breakdown

    t = np.arange(0, 2, 1 / 30)
    contact = np.ones(t.size, bool)
    contact[:5] = False
    truth = np.column_stack([10 * np.sin(t), 5 * np.cos(t), 3 + np.sin(2 * t)])
    master = truth + np.array([0.3, 0.0, 2.0])
    master[~contact, :2] = np.nan
    tl = np.arange(-0.1, 2.1, 0.001)
    slave = np.column_stack([10 * np.sin(tl) + 0.3, 5 * np.cos(tl) + 0.1,
                             5 + np.sin(2 * tl)])
    b = truth_breakdown(t, master, contact, tl, slave, t, truth, contact)
    assert b["master_vs_truth"] == pytest.approx({"x": 0.3, "y": 0.0, "z": 2.0}, abs=1e-3)
    assert b["slave_vs_master"] == pytest.approx({"x": 0.0, "y": 0.1, "z": 0.0}, abs=1e-3)
    assert b["slave_vs_truth"] == pytest.approx({"x": 0.3, "y": 0.1, "z": 2.0}, abs=1e-3)
    lines = breakdown_lines({"truth_breakdown_mm": b})
    assert len(lines) == 5 and lines[-1].endswith("largest part: indentation, 2.00 mm")
    assert breakdown_lines({"mae_mm": {}}) == []
