"""The bundled recordings: present, readable, small, and made by make_recordings.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from fydpad.synth import SyntheticPad
from vision.recording import PadRecording

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def _script():
    spec = importlib.util.spec_from_file_location("make_recordings",
                                                  RECORDINGS / "make_recordings.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_recordings_stay_under_12_mb():
    total = sum(p.stat().st_size for p in RECORDINGS.rglob("*") if p.is_file())
    assert total < 12_000_000


@pytest.mark.parametrize("name", ["circle", "lissajous", "tapping", "hard"])
def test_bundled_recording_matches_its_recipe(name):
    cfg = _script().RECORDINGS[name]
    rec = PadRecording(RECORDINGS / name)
    synthetic = rec.meta.extra["synthetic"]
    assert synthetic["seed"] == cfg.seed and synthetic["trajectory"] == cfg.trajectory
    truth = rec.read_truth()
    assert truth is not None and truth.t_s.size == rec.frame_count == cfg.frame_count
    assert truth.contact.any() and not truth.contact[:20].any()
    # The recipe renders the same frames (up to the mp4v coding) and the same truth.
    pad = SyntheticPad(cfg)
    k = int(np.flatnonzero(truth.contact)[len(np.flatnonzero(truth.contact)) // 2])
    assert pad.truth(k).x_mm == pytest.approx(truth.x_mm[k], abs=1e-5)
    for j, _, frame in rec.frames():
        if j == k:
            assert np.abs(frame.astype(float) - pad.frame(k)).mean() < 4.0
            break
