"""The robust tracker against truth on synthetic footage with the conditions of real
footage (issue 4): every condition alone, a mirrored camera, and the paper's method
beside it. Recordings are rendered by the synthetic pad, written as MJPG video and
decoded back by OpenCV."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fydpad.synth import Effects, SynthConfig, SyntheticPad
from vision.contact import ContactTracker
from vision.evaluation import TrackingScore, score_tracking
from vision.recording import PadRecording

CONDITIONS = ["none", "uneven_light", "room_light", "auto_exposure", "daylight", "stains",
              "hand_shadow", "light_touch", "fast", "hover"]


def track(recdir: Path, method: str) -> TrackingScore:
    rec = PadRecording(recdir)
    m = rec.meta
    truth = rec.read_truth()
    t = ContactTracker(roi_px=m.roi_px, workspace_mm=m.workspace_mm, image_flip=m.image_flip,
                       method=method)
    c, x, y = [], [], []
    for _, _, frame in rec.frames():
        r = t.process(frame)
        c.append(r is not None)
        x.append(r.x_mm if r else np.nan)
        y.append(r.y_mm if r else np.nan)
    return score_tracking(c, x, y, truth.contact, truth.x_mm, truth.y_mm)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("conditions")
    out = {}
    for name in CONDITIONS:
        effects = Effects() if name == "none" else Effects(**{name: True})
        cfg = SynthConfig(trajectory="walk", seconds=5.0, seed=5, effects=effects)
        out[name] = SyntheticPad(cfg).write(root / name) or root / name
    mirrored = SynthConfig(trajectory="walk", seconds=4.0, seed=8, image_flip="both")
    out["mirrored_both"] = SyntheticPad(mirrored).write(root / "both") or root / "both"
    return out


@pytest.mark.parametrize("condition", [c for c in CONDITIONS if c != "hover"] + ["mirrored_both"])
def test_robust_meets_the_targets(recordings, condition):
    s = track(recordings[condition], "robust")
    print(condition, s)
    assert s.contact_frames > 30
    assert s.missed == 0 and s.false == 0, s
    assert s.rmse_mm <= 0.3, s


@pytest.mark.xfail(strict=True, reason="known gap: a dark hovering fingertip's shadow, "
                   "a frame after release, still passes as a contact (1 false frame; RMSE "
                   "0.18 mm); see the issue note")
def test_robust_with_a_dark_hovering_finger(recordings):
    s = track(recordings["hover"], "robust")
    assert s.missed == 0 and s.false == 0, s
    assert s.rmse_mm <= 0.3, s


@pytest.mark.parametrize("condition", ["stains", "hand_shadow", "uneven_light"])
def test_the_papers_method_fails_where_robust_does_not(recordings, condition):
    """The conditions are hard: the paper's fixed threshold sees false contacts there."""
    assert track(recordings[condition], "paper").false > 10
