"""A video that ends before the recording's other files, really truncated on disk and
decoded by OpenCV: the offline commands say so in one line naming the file and the last
good frame, exit non-zero unless --allow-truncated, and keep the rows already written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

from fydpad.cli import main
from tests.conftest import REPO, write_blob_recording
from vision.recording import PadRecording, TruncatedVideo

N_FRAMES = 60


@pytest.fixture
def truncated(tmp_path: Path) -> tuple[Path, int]:
    """A 60-frame MJPG AVI cut to 40 % of its bytes; returns it and the frames OpenCV
    still decodes."""
    rec = tmp_path / "rec"
    write_blob_recording(rec, [(-30.0 + i, 10.0) for i in range(N_FRAMES)])
    video = rec / "video.avi"
    with video.open("r+b") as fh:
        fh.truncate(int(os.path.getsize(video) * 0.4))
    cap = cv2.VideoCapture(str(video))
    good = 0
    while cap.read()[0]:
        good += 1
    cap.release()
    assert 0 < good < N_FRAMES - 5
    return rec, good


def test_the_reader_stops_at_the_last_good_frame_and_names_it(truncated):
    rec, good = truncated
    frames = []
    with pytest.raises(TruncatedVideo, match=rf"video.avi: the video ends after frame "
                                             rf"{good - 1} .*truth.csv runs on to 1.97 s"):
        for k, _, _ in PadRecording(rec).frames():
            frames.append(k)
    assert frames == list(range(good))  # every good frame was delivered first


def test_track_exits_non_zero_and_keeps_the_rows(truncated, tmp_path, capsys):
    rec, good = truncated
    out = tmp_path / "track.csv"
    assert main(["track", str(rec), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"the video ends after frame {good - 1}" in err and "--allow-truncated" in err
    assert len(out.read_text().splitlines()) == 1 + good  # header + the good frames


def test_allow_truncated_warns_and_uses_the_frames(truncated, tmp_path):
    rec, good = truncated
    out = tmp_path / "track.csv"
    with pytest.warns(UserWarning, match=f"ends after frame {good - 1}.*--allow-truncated"):
        assert main(["track", str(rec), "--out", str(out), "--allow-truncated"]) == 0
    assert len(out.read_text().splitlines()) == 1 + good
    assert PadRecording.allow_truncated is False  # the option ends with the command


def test_a_complete_video_is_not_flagged(tmp_path):
    rec = tmp_path / "rec"
    write_blob_recording(rec, [(0.0, 0.0)] * 20)
    assert sum(1 for _ in PadRecording(rec).frames()) == 20


def test_a_corrupt_frame_mid_file_is_caught(tmp_path):
    """Zeros over a stretch in the middle: OpenCV stops decoding there."""
    rec = tmp_path / "rec"
    write_blob_recording(rec, [(-30.0 + i, 10.0) for i in range(N_FRAMES)])
    video = rec / "video.avi"
    size = os.path.getsize(video)
    with video.open("r+b") as fh:
        fh.seek(size // 2)
        fh.write(bytes(size // 10))
    with pytest.raises(TruncatedVideo, match=r"video\.avi: the video ends after frame"):
        for _ in PadRecording(rec).frames():
            pass


def test_the_station_replay_stops_safely_and_exits_non_zero(truncated, tmp_path):
    rec, good = truncated
    out = tmp_path / "station"
    proc = subprocess.run(
        [sys.executable, "-m", "fydpad.cli", "run", "--replay", str(rec), "--record", str(out),
         "--as-fast-as-possible"], capture_output=True, text=True, timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO)})
    assert proc.returncode == 2
    assert f"the video ends after frame {good - 1}" in proc.stderr
    assert len((out / "track.csv").read_text().splitlines()) == 1 + good
