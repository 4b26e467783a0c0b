"""Indentation in the finger-state stream: rest distances learned before the first contact."""

from __future__ import annotations

import numpy as np
import pytest

from vision.contact import Contact
from vision.indentation import IndentationEstimator
from vision.ir import distance_to_voltage_v
from vision.stream import FingerStateBuilder, LiveIndentation


def volts(d_mm):
    return distance_to_voltage_v(np.asarray(d_mm, float))


def test_live_indentation_learns_rest_then_measures_a_press():
    live = LiveIndentation(IndentationEstimator())
    rest = np.array([98.0, 103.0, 100.0])  # each sensor its own rest distance
    # Frames at 10 Hz, each with the board's 10 samples (100 Hz) since the previous one.
    for f in range(20):
        t = f * 0.1 + np.arange(-9, 1) * 0.01
        assert live.update(t, volts(np.tile(rest, (10, 1))), f * 0.1, None) == 0.0
    # The fabric pushed 12 mm down evenly and held for three frames: every sensor 12 mm
    # closer; the filter has settled on it.
    c = Contact(5.0, 4.0, 0.0, 0.0, 50.0)
    for f in range(20, 23):
        t = f * 0.1 + np.arange(-9, 1) * 0.01
        ind = live.update(t, volts(np.tile(rest - 12.0, (10, 1))), f * 0.1, c)
    assert ind == pytest.approx(12.0, abs=0.3)
    assert live.estimator.baseline_mm == pytest.approx(tuple(rest), abs=0.2)


def test_no_ir_yet_is_nan():
    live = LiveIndentation(IndentationEstimator())
    c = Contact(0, 0, 0, 0, 1)
    assert np.isnan(live.update(np.empty(0), np.empty((0, 3)), 0.0, c))
    assert np.isnan(live.update([0.01], [[np.nan] * 3], 0.02, c))  # an invalid sample


def test_builder_speed_and_zero_indentation_without_contact():
    b = FingerStateBuilder()
    s0 = b.build(0.0, None, indentation_mm=3.0)
    assert not s0.contact and s0.indentation_mm == 0.0 and s0.speed_mm_s == 0.0
    assert np.isnan(b.build(0.1, None).indentation_mm)
    b.build(0.2, Contact(0.0, 0.0, 0, 0, 1.0))
    s = b.build(0.3, Contact(3.0, 4.0, 0, 0, 1.0))
    assert s.contact and 0 < s.speed_mm_s <= 50.0
