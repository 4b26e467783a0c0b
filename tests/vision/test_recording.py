"""Readers and writers of docs/recording_format.md, and their errors naming file and key/line."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

from vision.recording import (
    PadMeta,
    PadRecording,
    RecordingError,
    TrackWriter,
    parse_meta,
    read_csv_columns,
    read_track,
    write_meta,
)


def test_meta_defaults_and_round_trip(tmp_path: Path):
    meta = parse_meta({"roi_px": [24, 22, 592, 414], "workspace_mm": [100, 70], "fps": 30,
                       "my_key": {"a": 1}})
    assert meta.image_flip == "none"
    assert meta.ir_sensors_mm == ((-22.0, -3.0), (0.0, 27.0), (22.0, -3.0))
    assert meta.base_to_fabric_mm == 100.0 and meta.ir_baseline_mm is None
    write_meta(tmp_path, meta)
    data = json.loads((tmp_path / "meta.json").read_text())
    assert data["my_key"] == {"a": 1}  # unknown keys survive a rewrite
    assert parse_meta(data) == meta


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"workspace_mm": [100, 70]}, "missing required key 'roi_px'"),
        ({"roi_px": [0, 0, 10, 10]}, "missing required key 'workspace_mm'"),
        ({"roi_px": [0, 0, 10], "workspace_mm": [100, 70]}, "key 'roi_px'"),
        ({"roi_px": "0,0,10,10", "workspace_mm": [100, 70]}, "key 'roi_px'"),
        ({"roi_px": [0, 0, 10, 10], "workspace_mm": [100, "70"]}, "key 'workspace_mm'"),
        ({"roi_px": [0, 0, 10, 10], "workspace_mm": [100, 70], "fps": -1}, "key 'fps'"),
        ({"roi_px": [0, 0, 10, 10], "workspace_mm": [100, 70], "image_flip": "up"},
         "key 'image_flip'"),
        ({"roi_px": [0, 0, 10, 10], "workspace_mm": [100, 70], "ir": {"sensors_mm": [[0, 0]]}},
         "key 'ir.sensors_mm'"),
        ({"roi_px": [600, 0, 100, 10], "workspace_mm": [100, 70], "frame_size": [640, 480]},
         "outside frame_size"),
        ({"roi_px": [0, 0, 10, 10], "workspace_mm": [100, 70],
          "ir": {"sensors_mm": [[0, 0], [10, 10], [20, 20]]}}, "collinear"),
    ],
)
def test_meta_errors_name_the_key(data, message):
    with pytest.raises(RecordingError, match=r"meta\.json") as err:
        parse_meta(data, "rec/meta.json")
    assert message in str(err.value)


def test_recording_round_trip(blob_recording: Path):
    rec = PadRecording(blob_recording)
    assert rec.meta.image_flip == "horizontal"
    assert rec.frame_count == 13 and rec.video_size == (640, 480)
    frames = list(rec.frames())
    assert [k for k, _, _ in frames] == list(range(13))
    assert frames[3][1] == pytest.approx(3 / 30)
    assert frames[0][2].shape == (480, 640, 3)
    t, v = rec.read_ir()
    assert t[1] == pytest.approx(1 / 30, abs=1e-6)
    assert v.shape == (13, 3) and np.allclose(v, 1.31)
    truth = rec.read_truth()
    assert truth.contact.tolist() == [False] * 2 + [True] * 10 + [False]
    assert np.isnan(truth.x_mm[0]) and truth.x_mm[2] == pytest.approx(-30.0)
    assert rec.read_force()[1][5] == pytest.approx(2.0)


def test_frames_csv_gives_uneven_times(blob_recording: Path):
    times = [0.0, 0.03, 0.07, 0.1, 0.15, 0.2, 0.21, 0.3, 0.31, 0.4, 0.45, 0.5, 0.52]
    (blob_recording / "frames.csv").write_text(
        "t_s,frame\n" + "".join(f"{t},{k}\n" for k, t in enumerate(times)))
    rec = PadRecording(blob_recording)
    assert [t for _, t, _ in rec.frames()] == pytest.approx(times)


def test_missing_fps_is_fine_with_frames_csv_only(blob_recording: Path):
    meta = json.loads((blob_recording / "meta.json").read_text())
    del meta["fps"]
    (blob_recording / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(RecordingError, match="missing required key 'fps'"):
        PadRecording(blob_recording)
    (blob_recording / "frames.csv").write_text(
        "t_s,frame\n" + "".join(f"{k / 25},{k}\n" for k in range(13)))
    assert PadRecording(blob_recording).fps == pytest.approx(25.0)


def test_malformed_csv_names_file_line_and_column(tmp_path: Path):
    p = tmp_path / "ir.csv"
    p.write_text("t_s,v0,v1,v2\n0.0,1,1,1\n0.01,1,oops,1\n")
    with pytest.raises(RecordingError, match=r"ir\.csv: line 3: column 'v1': 'oops'"):
        read_csv_columns(p, ("t_s", "v0", "v1", "v2"))
    p.write_text("t_s,v0,v1,v2\n0.0,1,1,1\n0.01,1,1\n")
    with pytest.raises(RecordingError, match="line 3: expected 4 fields, got 3"):
        read_csv_columns(p, ("t_s", "v0", "v1", "v2"))
    p.write_text("t_s,v0,v1\n0.0,1,1\n")
    with pytest.raises(RecordingError, match="line 1: missing column"):
        read_csv_columns(p, ("t_s", "v0", "v1", "v2"))


def test_time_going_back_is_named(blob_recording: Path):
    (blob_recording / "ir.csv").write_text("t_s,v0,v1,v2\n0.0,1,1,1\n0.1,1,1,1\n0.05,1,1,1\n")
    with pytest.raises(RecordingError, match=r"ir\.csv: line 4: column 't_s' goes back"):
        PadRecording(blob_recording).read_ir()


def test_frame_size_mismatch_is_named(blob_recording: Path):
    meta = json.loads((blob_recording / "meta.json").read_text())
    meta["frame_size"] = [320, 240]
    meta["roi_px"] = [0, 0, 320, 240]
    (blob_recording / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(RecordingError, match=r"frame_size.*is 640x480"):
        PadRecording(blob_recording)


def test_unreadable_video_is_named(blob_recording: Path):
    (blob_recording / "video.avi").write_bytes(b"this is not a video" * 100)
    with pytest.raises(RecordingError, match=r"video\.avi: OpenCV cannot open it"):
        PadRecording(blob_recording)
    (blob_recording / "video.avi").unlink()
    with pytest.raises(RecordingError, match="missing video"):
        PadRecording(blob_recording)


def test_track_writer_rows_and_reader(tmp_path: Path):
    p = tmp_path / "track.csv"
    with TrackWriter(p, extra_columns=("area_mm2",)) as w:
        w.write_row(0.0, 0, False, None, None, 3.0, None)
        w.write_row(1 / 30, 1, True, 1.25, -2.5, 4.5, 80.0)
        w.write_row(2 / 30, 2, True, 1.5, -2.0, None, 81.0)
    lines = p.read_text().splitlines()
    assert lines[0] == "t_s,frame,contact,x_mm,y_mm,indentation_mm,area_mm2"
    assert lines[1] == "0,0,0,,,0,"  # no contact: x, y empty and indentation 0
    assert lines[2] == "0.033333,1,1,1.25,-2.5,4.5,80"
    assert lines[3].split(",")[5] == ""  # no IR: indentation empty
    cols = read_track(p)
    assert cols["x_mm"][1] == 1.25 and np.isnan(cols["x_mm"][0])


def test_writer_keeps_rows_when_not_closed(tmp_path: Path):
    p = tmp_path / "track.csv"
    w = TrackWriter(p)
    for k in range(100):
        w.write_row(k / 30, k, True, 0.0, 0.0, None)
    time.sleep(0.6)  # longer than the writer's flush interval (0.5 s)
    w.write_row(100 / 30, 100, True, 0.0, 0.0, None)
    # Not closed (as if the process were killed): all rows up to the flush are on disk.
    assert len(read_track(p)["t_s"]) == 101
    w.close()


def test_meta_written_by_writer_is_read_back(tmp_path: Path):
    from vision.recording import PadRecordingWriter
    meta = PadMeta(roi_px=(0, 0, 64, 48), workspace_mm=(100.0, 70.0), fps=10.0,
                   frame_size=(64, 48), image_flip="both", ir_baseline_mm=(99.0, 100.0, 101.0))
    with PadRecordingWriter(tmp_path / "r", meta, video_name="video.mp4") as w:
        for _ in range(3):
            w.write_frame(np.zeros((48, 64, 3), np.uint8))
    rec = PadRecording(tmp_path / "r")
    assert rec.meta.ir_baseline_mm == (99.0, 100.0, 101.0)
    assert rec.video_path.name == "video.mp4" and rec.frame_count == 3


def test_mjpg_quality_is_honoured(tmp_path: Path):
    from vision.recording import PadRecordingWriter
    rng = np.random.default_rng(0)
    frame = rng.integers(100, 200, (120, 160, 3), dtype=np.uint8)
    sizes = {}
    for q in (40, 95):
        meta = PadMeta(roi_px=(0, 0, 160, 120), workspace_mm=(100.0, 70.0), fps=30.0,
                       frame_size=(160, 120))
        with PadRecordingWriter(tmp_path / f"q{q}", meta, jpeg_quality=q) as w:
            for _ in range(3):
                w.write_frame(frame)
        sizes[q] = (tmp_path / f"q{q}" / "video.avi").stat().st_size
        assert PadRecording(tmp_path / f"q{q}").frame_count == 3
    assert sizes[95] > sizes[40] * 1.1
