"""A live camera that drops frames: counted (stats, events.csv), never fatal; a sustained
outage stops the station safely with one line naming the camera.

A real camera cannot run here: ``FakeCapture`` stands in for ``cv2.VideoCapture`` (the
only mock: the station, its render process, its recording and the CLI are the real
ones). It serves a dark blob at 30 fps in real time and fails the reads its script says,
as a USB camera does (a failed ``read()`` returns at once with no image).
"""

from __future__ import annotations

import csv
import json
import time
from typing import ClassVar

import cv2
import numpy as np
import pytest

import vision.sources
from fydpad.cli import main as cli_main
from vision.sources import CameraConfig, CameraSource, SourceError

FPS = 30.0
REAL_CAPTURE = cv2.VideoCapture  # reads the recorded video back


def video_frames(path) -> int:
    cap = REAL_CAPTURE(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


class FakeCapture:
    """A ``cv2.VideoCapture`` stand-in: frame k is served 1/FPS after frame k-1; the reads
    numbered in ``fail`` (or from ``fail_from`` on) fail."""

    fail: ClassVar[set[int]] = set()
    fail_from: ClassVar[int | None] = None
    last: ClassVar[FakeCapture]

    def __init__(self, device):
        FakeCapture.last = self
        self.device = device
        self.served = 0
        self.reads = 0
        self.next_t = time.monotonic()

    def isOpened(self) -> bool:
        return True

    def set(self, prop, value) -> bool:
        return True

    def get(self, prop) -> float:
        return {cv2.CAP_PROP_FPS: FPS, cv2.CAP_PROP_FRAME_WIDTH: 640,
                cv2.CAP_PROP_FRAME_HEIGHT: 480}.get(prop, 0.0)

    def read(self):
        k = self.reads
        self.reads += 1
        if k in self.fail or (self.fail_from is not None and k >= self.fail_from):
            return False, None
        delay = self.next_t - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        self.next_t = max(self.next_t, time.monotonic()) + 1 / FPS
        self.served += 1
        img = np.full((480, 640, 3), 225, np.uint8)
        u = 200 + (k % 60) * 4
        img[228:252, u - 12:u + 12] = 40
        return True, img

    def release(self) -> None:
        pass


@pytest.fixture
def fake_camera(monkeypatch):
    monkeypatch.setattr(vision.sources.cv2, "VideoCapture", FakeCapture)
    monkeypatch.setattr(FakeCapture, "fail", set())
    monkeypatch.setattr(FakeCapture, "fail_from", None)
    return FakeCapture


def test_source_counts_dropped_frames_and_keeps_going(fake_camera):
    fake_camera.fail = {10, 11, 12, 30}
    src = CameraSource(CameraConfig(device="0"))
    frames = []
    for f in src.frames():
        frames.append(f)
        if len(frames) == 40:
            break
    assert [f.index for f in frames] == list(range(40))  # indices stay consecutive
    assert src.read_failures == 4
    # Two outages: 3 failed reads after frame 9, 1 after frame 26 (reads 10-12 failed).
    assert [(d[1], d[2]) for d in src.dropouts] == [(9, 3), (26, 1)]
    assert src.dropouts[0][0] == pytest.approx(frames[9].t_s)


def test_source_gives_up_after_a_sustained_outage(fake_camera):
    fake_camera.fail_from = 15
    src = CameraSource(CameraConfig(device="0", outage_timeout_s=0.5))
    got = []
    t0 = time.monotonic()
    with pytest.raises(SourceError, match=r"camera '0': no frame for 0\.5 s after frame 14"):
        for f in src.frames():
            got.append(f.index)
    assert got == list(range(15))
    assert 0.5 <= time.monotonic() - t0 < 5.0  # it waited out the outage, then gave up


def test_station_counts_dropped_frames_in_stats_and_events(fake_camera, tmp_path, capsys):
    fake_camera.fail = {20, 21, 22, 23, 24, 40, 41}
    rc = cli_main(["run", "--camera", "0", "--duration", "6", "--record",
                   str(tmp_path / "rec"), "--stats", str(tmp_path / "stats.json")])
    assert rc == 0, capsys.readouterr().err
    assert "7 dropped by the camera in 2 outages" in capsys.readouterr().out
    vision_stats = json.loads((tmp_path / "stats.json").read_text())["vision"]
    assert vision_stats["camera_read_failures"] == 7
    assert vision_stats["camera_outages"] == 2
    with (tmp_path / "rec" / "events.csv").open() as fh:
        drops = [r for r in csv.DictReader(fh) if r["event"] == "camera_dropout"]
    assert [r["detail"].split(":")[0] for r in drops] == ["camera '0'"] * 2
    assert "5 failed reads" in drops[0]["detail"] and "after frame 19" in drops[0]["detail"]
    assert "2 failed reads" in drops[1]["detail"] and "after frame 34" in drops[1]["detail"]
    # It ran on past both outages, recording every frame the camera gave.
    assert fake_camera.last.reads > 42
    assert video_frames(tmp_path / "rec" / "video.avi") == fake_camera.last.served


def test_station_stops_safely_on_a_camera_outage(fake_camera, tmp_path, capsys):
    fake_camera.fail_from = 45
    rc = cli_main(["run", "--camera", "0", "--duration", "30", "--record",
                   str(tmp_path / "rec")])
    err = capsys.readouterr().err
    assert rc == 2
    line = [s for s in err.splitlines() if "error" in s][-1]
    assert "station stopped safely" in line and "camera '0': no frame for 2.0 s" in line
    assert "after frame 44" in line
    # Every frame before the outage kept.
    assert video_frames(tmp_path / "rec" / "video.avi") == 45
