"""The robust tracker against truth on synthetic footage with the conditions of real
footage: every condition alone, a mirrored camera, and the paper's method
beside it. Recordings are rendered by the synthetic pad, written as MJPG video and
decoded back by OpenCV.

Two seeds per condition (seed 6 found a light touch and a hovering finger's ghost
that seed 5 alone passed). A frame during whose exposure the finger touched down or
lifted off shows the camera part of a contact, so either answer is right there: those
frames count in the position error but not as missed or false
(``SyntheticPad.straddles_contact``); every other frame must be answered right."""

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
SEEDS = (5, 6)


def track(recdir: Path, method: str, straddling=None) -> TrackingScore:
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
    return score_tracking(c, x, y, truth.contact, truth.x_mm, truth.y_mm, straddling)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> dict[str, tuple[Path, np.ndarray]]:
    """name -> (recording, the frames whose exposure straddles a touch or a release)."""
    root = tmp_path_factory.mktemp("conditions")
    out = {}

    def make(key: str, cfg: SynthConfig) -> None:
        pad = SyntheticPad(cfg)
        pad.write(root / key)
        out[key] = root / key, np.array([pad.straddles_contact(k)
                                         for k in range(pad.frame_count)])

    for name in CONDITIONS:
        effects = Effects() if name == "none" else Effects(**{name: True})
        for seed in SEEDS:
            make(f"{name}-{seed}", SynthConfig(trajectory="walk", seconds=5.0, seed=seed,
                                               effects=effects))
    make("mirrored_both", SynthConfig(trajectory="walk", seconds=4.0, seed=8,
                                      image_flip="both"))
    return out


@pytest.mark.parametrize("key", [f"{c}-{s}" for c in CONDITIONS for s in SEEDS]
                         + ["mirrored_both"])
def test_robust_meets_the_targets(recordings, key):
    s = track(*recordings[key][:1], "robust", recordings[key][1])
    print(key, s)
    assert s.contact_frames > 30
    assert s.missed == 0 and s.false == 0, s
    assert s.rmse_mm <= 0.3, s


def test_straddling_frames_are_few_and_next_to_a_change(recordings):
    """The frames left out of missed/false are only some of those at a touch or a
    release: a touch-down or a lift-off falls within at most one exposure (shorter than
    the frame interval), and each one changes the truth between two frames."""
    left_out = changes = 0
    for path, straddling in recordings.values():
        c = np.asarray(PadRecording(path).read_truth().contact, bool)
        change = np.zeros(c.size, bool)
        change[1:] |= c[1:] != c[:-1]
        change[:-1] |= c[:-1] != c[1:]
        assert not np.any(straddling & ~change), path
        left_out += int(straddling.sum())
        changes += int(change.sum())
    assert 0 < left_out <= changes // 2, (left_out, changes)


@pytest.mark.parametrize("condition", ["stains", "hand_shadow", "uneven_light"])
def test_the_papers_method_fails_where_robust_does_not(recordings, condition):
    """The conditions are hard: the paper's fixed threshold sees false contacts there."""
    assert track(recordings[f"{condition}-5"][0], "paper").false > 10
