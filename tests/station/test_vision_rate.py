"""`fydpad run --vision-hz`: the vision loop tracks at that rate (the paper's 10 Hz),
dropping the frames in between rather than queueing them, and tele-operation follows
at the vision rate; the sensors are recorded at their own rate (100 Hz here), every
sample. Counts are derived from the recording's own frame and sample times: as fast as
possible (``--as-fast-as-possible``) those times are the station's clock; in real time
the assertions hold however late the machine runs the loops."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main
from tests.conftest import write_blob_recording
from vision.recording import CsvRowWriter, PadRecording, read_track

N_FRAMES = 48
IR_HZ = 100.0


@pytest.fixture(scope="module")
def rec(tmp_path_factory) -> Path:
    rec = tmp_path_factory.mktemp("vr") / "circle"
    pos = [None] * 4 + [(20 * np.cos(k / 8), 15 * np.sin(k / 8)) for k in range(40)] + [None] * 4
    write_blob_recording(rec, pos, fps=30.0)
    # The IR sensors at their own rate, each sample distinct, some after the last frame.
    w = CsvRowWriter(rec / "ir.csv", ("t_s", "v0", "v1", "v2"))
    for k in range(int(1.7 * IR_HZ)):
        w.write(k / IR_HZ, 1.2 + 0.001 * k, 1.3 + 0.001 * k, 1.4 - 0.001 * k)
    w.close()
    return rec


def expected_frames(rec: Path, vision_hz: float) -> list[int]:
    """The frames whose time reaches the next 1/vision_hz slot of the recording's clock
    (frame k at k / fps; a frame counts for its slot up to half a frame early)."""
    fps = PadRecording(rec).meta.fps
    t = np.arange(N_FRAMES) / fps
    slots = np.floor(t * vision_hz + 0.5 * vision_hz / fps + 1e-9)
    return [k for k in range(N_FRAMES) if k == 0 or slots[k] > slots[k - 1]]


@pytest.mark.parametrize("vision_hz", [10.0, 15.0])
def test_vision_tracks_at_the_requested_rate(rec: Path, tmp_path: Path, vision_hz: float):
    from teleop.config import TeleopConfig
    from teleop.slave import SlaveThread

    want = expected_frames(rec, vision_hz)
    assert len(want) < N_FRAMES  # the rate really is below the camera's
    with SlaveThread(TeleopConfig(), bind="tcp://127.0.0.1:*") as slave:
        rc = main(["run", "--replay", str(rec), "--vision-hz", str(vision_hz),
                   "--as-fast-as-possible", "--no-realtime", "--teleop", slave.endpoint,
                   "--record", str(tmp_path / "s"), "--stats", str(tmp_path / "st.json")])
    assert rc == 0
    stats = json.loads((tmp_path / "st.json").read_text())
    v = stats["vision"]
    assert v["target_hz"] == vision_hz
    assert v["ticks"] == len(want)
    assert v["frames_dropped"] == N_FRAMES - len(want)
    # Tracked are exactly the frames of each slot, in order.
    track = read_track(tmp_path / "s" / "track.csv")
    assert track["frame"].astype(int).tolist() == want
    # The video keeps every frame, so the session replays as shot.
    assert PadRecording(tmp_path / "s").frame_count == N_FRAMES
    # Tele-operation at the vision rate: one message per tracked frame, and the hold.
    assert stats["link"]["sent"] == len(want) + 1
    # The sensors are recorded at their own rate, not the vision rate: every replayed
    # sample comes back at its own time stamp, those between dropped frames and after
    # the last frame included.
    src, got = PadRecording(rec), PadRecording(tmp_path / "s")
    for a, b in ((src.read_ir(), got.read_ir()), (src.read_force(), got.read_force())):
        assert len(b[0]) == len(a[0])
        np.testing.assert_allclose(b[0], a[0])
        np.testing.assert_allclose(b[1], a[1])


def test_real_time_records_every_sensor_sample_due_before_the_stop(rec: Path, tmp_path: Path):
    """In real time the replayed sensors follow the station's clock in a thread of their
    own; however late the machine runs it, every sample due by the last tracked frame's
    time (the station stops after it) is recorded, in order, at its own time stamp."""
    want = expected_frames(rec, 10.0)
    rc = main(["run", "--replay", str(rec), "--vision-hz", "10", "--no-realtime",
               "--record", str(tmp_path / "s")])
    assert rc == 0
    src = PadRecording(rec).read_ir()
    got = PadRecording(tmp_path / "s").read_ir()
    due = int(np.count_nonzero(src[0] <= want[-1] / PadRecording(rec).meta.fps))
    n = len(got[0])
    assert due <= n <= len(src[0])
    np.testing.assert_allclose(got[0], src[0][:n])
    np.testing.assert_allclose(got[1], src[1][:n])


def test_default_tracks_every_frame(rec: Path, tmp_path: Path):
    rc = main(["run", "--replay", str(rec), "--no-realtime", "--stats",
               str(tmp_path / "st.json")])
    assert rc == 0
    v = json.loads((tmp_path / "st.json").read_text())["vision"]
    assert v["ticks"] == N_FRAMES and v["frames_dropped"] == 0 and v["target_hz"] == 30.0


def test_vision_rate_above_the_camera_is_the_camera_rate(rec: Path, tmp_path: Path):
    rc = main(["run", "--replay", str(rec), "--no-realtime", "--vision-hz", "100",
               "--stats", str(tmp_path / "st.json")])
    assert rc == 0
    v = json.loads((tmp_path / "st.json").read_text())["vision"]
    assert v["ticks"] == N_FRAMES and v["target_hz"] == 30.0


@pytest.mark.parametrize("hz", ["0", "-5", "nan"])
def test_bad_vision_rate_is_one_line(rec: Path, hz: str, capsys):
    assert main(["run", "--replay", str(rec), "--vision-hz", hz]) == 2
    err = capsys.readouterr().err
    assert "--vision-hz" in err and len(err.strip().splitlines()) == 1
