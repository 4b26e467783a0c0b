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
    for _ in range(20):
        assert live.update(volts(rest), None) == 0.0
    # The fabric pushed 12 mm down evenly: every sensor 12 mm closer.
    c = Contact(5.0, 4.0, 0.0, 0.0, 50.0)
    assert live.update(volts(rest - 12.0), c) == pytest.approx(12.0, abs=0.3)
    assert live.estimator.baseline_mm == pytest.approx(tuple(rest), abs=0.2)


def test_no_ir_yet_is_nan():
    live = LiveIndentation(IndentationEstimator())
    assert np.isnan(live.update([np.nan] * 3, Contact(0, 0, 0, 0, 1)))


def test_builder_speed_and_zero_indentation_without_contact():
    b = FingerStateBuilder()
    s0 = b.build(0.0, None, indentation_mm=3.0)
    assert not s0.contact and s0.indentation_mm == 0.0 and s0.speed_mm_s == 0.0
    assert np.isnan(b.build(0.1, None).indentation_mm)
    b.build(0.2, Contact(0.0, 0.0, 0, 0, 1.0))
    s = b.build(0.3, Contact(3.0, 4.0, 0, 0, 1.0))
    assert s.contact and 0 < s.speed_mm_s <= 50.0
