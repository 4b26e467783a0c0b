"""Replay backends read a recording's ir.csv / force.csv through PadRecording."""

from __future__ import annotations

import math

import pytest

from vision.config import IRConfig
from vision.recording import PadRecording
from vision.sensors import (
    ForceSource,
    IRSource,
    ReplayForce,
    ReplayIR,
    SensorError,
)


def test_replay_from_a_recording(blob_recording):
    rec = PadRecording(blob_recording)
    ir = ReplayIR.from_recording(rec)
    force = ReplayForce.from_recording(rec)
    assert isinstance(ir, IRSource) and isinstance(force, ForceSource)
    samples = []
    while (s := ir.read()) is not None:
        samples.append(s)
    t, volts = rec.read_ir()
    assert len(samples) == t.size
    assert samples[3].t_s == pytest.approx(t[3]) and samples[3].volts == pytest.approx(volts[3])
    assert all(s.valid == (True, True, True) for s in samples)
    forces = []
    while (f := force.read()) is not None:
        forces.append(f)
    assert [f.force_n for f in forces] == pytest.approx(list(rec.read_force()[1]))
    assert ir.read() is None  # ended stays ended


def test_replay_flags_invalid_and_saturated():
    ir = ReplayIR([0.0, 0.01], [[1.3, 0.2, math.nan], [1.3, 1.3, 1.3]], IRConfig())
    s = ir.read()
    assert s.valid == (True, False, False)
    assert s.volts[0] == 1.3
    f = ReplayForce([0.0, 0.1], [7.0, 7.7])
    assert [f.read().saturated, f.read().saturated] == [False, True]


def test_missing_files_are_named(blob_recording):
    (blob_recording / "ir.csv").unlink()
    (blob_recording / "force.csv").unlink()
    rec = PadRecording(blob_recording)
    with pytest.raises(SensorError, match=r"ir\.csv"):
        ReplayIR.from_recording(rec)
    with pytest.raises(SensorError, match=r"force\.csv"):
        ReplayForce.from_recording(rec)
