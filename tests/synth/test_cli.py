"""`fydpad synth` end to end: the recording parses, decodes, is reproducible; bad input."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main
from fydpad.synth import EFFECT_HELP, SynthConfig, SyntheticPad, TrajectoryParams
from fydpad.synth.check import check_recording
from vision.recording import PadRecording


def test_synth_writes_a_recording_the_reader_accepts(tmp_path: Path, capsys):
    out = tmp_path / "rec"
    assert main(["synth", str(out), "--trajectory", "tapping", "--seconds", "1",
                 "--seed", "3"]) == 0
    assert "30 frames" in capsys.readouterr().out
    rec = PadRecording(out)
    assert rec.meta.image_flip == "horizontal"
    assert rec.meta.roi_px == (24, 22, 592, 414)
    assert rec.meta.workspace_mm == (100.0, 70.0)
    assert rec.meta.extra["synthetic"]["seed"] == 3
    assert rec.video_path.name == "video.avi"
    frames = list(rec.frames())
    assert len(frames) == 30 and frames[0][2].shape == (480, 640, 3)
    truth = rec.read_truth()
    assert truth is not None and truth.t_s.size == 30
    np.testing.assert_allclose(truth.t_s, np.arange(30) / 30.0, atol=1e-6)
    t_ir, v = rec.read_ir()
    assert t_ir.size == 100 and v.shape == (100, 3)
    t_f, _f = rec.read_force()
    assert t_f.size == 100


def test_same_seed_same_recording(tmp_path: Path):
    for name in ("a", "b"):
        assert main(["synth", str(tmp_path / name), "--trajectory", "walk", "--seconds",
                     "0.5", "--seed", "9", "--stains", "--video", "video.mp4"]) == 0
    for f in ("truth.csv", "ir.csv", "force.csv", "meta.json"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()
    fa = [fr for _, _, fr in PadRecording(tmp_path / "a").frames()]
    fb = [fr for _, _, fr in PadRecording(tmp_path / "b").frames()]
    assert len(fa) == 15
    for x, y in zip(fa, fb, strict=True):
        np.testing.assert_array_equal(x, y)


def test_flip_and_effects_reach_the_recording(tmp_path: Path):
    out = tmp_path / "rec"
    assert main(["synth", str(out), "--seconds", "0.2", "--flip", "none",
                 "--all-effects"]) == 0
    meta = PadRecording(out).meta
    assert meta.image_flip == "none"
    assert sorted(meta.extra["synthetic"]["effects"]) == sorted(EFFECT_HELP)
    assert meta.extra["synthetic"]["exposure_s"] == pytest.approx(1 / 30)


def test_help_explains_every_flag(capsys):
    with pytest.raises(SystemExit):
        main(["synth", "--help"])
    text = capsys.readouterr().out
    for name in EFFECT_HELP:
        assert f"--{name.replace('_', '-')}" in text
    for flag in ("--trajectory", "--seconds", "--seed", "--flip", "--all-effects",
                 "--video", "--mjpg-quality", "--exposure"):
        assert flag in text


@pytest.mark.parametrize("args, message", [
    (["--seconds", "0"], "--seconds must be positive"),
    (["--exposure", "0.1"], "--exposure must be in"),
    (["--mjpg-quality", "120"], "--mjpg-quality must be in 0..100"),
])
def test_bad_arguments_give_one_line_and_exit_2(tmp_path: Path, capsys, args, message):
    assert main(["synth", str(tmp_path / "x"), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_outdir_that_is_a_file_is_refused(tmp_path: Path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["synth", str(f), "--seconds", "0.1"]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_the_papers_tracker_follows_clean_footage(tmp_path: Path):
    """On clean footage the paper's method is within ~1 mm of the truth, with no false
    contact away from touches and releases."""
    cfg = SynthConfig(trajectory="circle", seconds=3.0, seed=4,
                      path=TrajectoryParams(lead_in_s=0.3, far_height_mm=16.0))
    SyntheticPad(cfg).write(tmp_path / "clean")
    r = check_recording(tmp_path / "clean", "paper")
    assert r.tracking.contact_frames > 30
    assert r.tracking.rmse_mm < 0.5 and r.tracking.max_error_mm < 1.0
    assert r.steady.false == 0 and r.steady.missed == 0


def test_the_papers_tracker_fails_under_the_hand_and_stains(tmp_path: Path):
    cfg = SynthConfig(trajectory="circle", seconds=3.0, seed=4,
                      path=TrajectoryParams(lead_in_s=0.3, far_height_mm=16.0))
    hard = replace(cfg, effects=replace(cfg.effects, stains=True, hand_shadow=True))
    SyntheticPad(hard).write(tmp_path / "hard")
    r = check_recording(tmp_path / "hard", "paper")
    assert r.steady.false > 5 or r.tracking.rmse_mm > 2.0


def test_the_pad_serves_vision_s_device_interfaces():
    from fydpad.synth.sources import SynthFrameSource, synth_force_source, synth_ir_source
    from vision.sensors import ForceSource, IRSource
    from vision.sources import FrameSource

    pad = SyntheticPad(SynthConfig(trajectory="circle", seconds=0.2, seed=1))
    src = SynthFrameSource(pad)
    assert isinstance(src, FrameSource)
    frames = list(src.frames())
    assert [f.index for f in frames] == list(range(6))
    np.testing.assert_array_equal(frames[3].image, pad.frame(3))
    ir, force = synth_ir_source(pad), synth_force_source(pad)
    assert isinstance(ir, IRSource) and isinstance(force, ForceSource)
    s = ir.read()
    assert s is not None and s.t_s == 0.0 and all(s.valid)
    assert force.read() is not None


def test_an_existing_recording_is_kept_unless_forced(tmp_path: Path, capsys):
    out = tmp_path / "rec"
    assert main(["synth", str(out), "--seconds", "0.1"]) == 0
    (out / "notes.txt").write_text("mine")
    assert main(["synth", str(out), "--seconds", "0.1", "--video", "video.mp4"]) == 2
    assert "--force" in capsys.readouterr().err
    assert main(["synth", str(out), "--seconds", "0.1", "--video", "video.mp4",
                 "--force"]) == 0
    # The old video is gone (a reader would pick it before video.mp4); other files stay.
    assert not (out / "video.avi").exists() and (out / "video.mp4").exists()
    assert (out / "notes.txt").read_text() == "mine"
