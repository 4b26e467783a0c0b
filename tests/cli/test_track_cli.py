"""`fydpad track` end to end on small recordings, and its one-line errors on bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main
from vision.recording import PadRecording, read_track


def test_track_writes_the_format_and_matches_truth(blob_recording: Path, tmp_path: Path, capsys):
    out = tmp_path / "track.csv"
    rc = main(["track", str(blob_recording), "--out", str(out), "--method", "paper",
               "--plot", str(tmp_path / "t.png"), "--video", str(tmp_path / "a.mp4"),
               "--json", str(tmp_path / "s.json")])
    assert rc == 0
    header = out.read_text().splitlines()[0].split(",")
    assert header[:6] == ["t_s", "frame", "contact", "x_mm", "y_mm", "indentation_mm"]
    cols = read_track(out)
    truth = PadRecording(blob_recording).read_truth()
    assert cols["frame"].tolist() == list(range(13))
    assert (cols["contact"] != 0).tolist() == truth.contact.tolist()
    c = truth.contact
    err = np.hypot(cols["x_mm"][c] - truth.x_mm[c], cols["y_mm"][c] - truth.y_mm[c])
    assert err.max() < 0.3  # the blob is centred on the truth to within half a pixel
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["truth"]["missed"] == 0 and summary["truth"]["false"] == 0
    assert (tmp_path / "t.png").stat().st_size > 10_000
    import cv2
    cap = cv2.VideoCapture(str(tmp_path / "a.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 13
    assert "RMSE" in capsys.readouterr().out


def test_track_on_unflipped_camera_reads_image_flip(blob_recording: Path, tmp_path: Path):
    from tests.conftest import write_blob_recording
    rec = tmp_path / "plain"
    write_blob_recording(rec, [None, (30.0, -20.0)], image_flip="none")
    for method in ("paper", "robust"):
        out = tmp_path / f"{method}.csv"
        assert main(["track", str(rec), "--out", str(out), "--method", method]) == 0
        cols = read_track(out)
        assert cols["contact"].tolist() == [0, 1]
        assert cols["x_mm"][1] == pytest.approx(30.0, abs=0.3)
        assert cols["y_mm"][1] == pytest.approx(-20.0, abs=0.3)


def _break(rec: Path, case: str) -> str:
    """Damage a recording; return the text the error line must contain."""
    if case == "no video":
        (rec / "video.avi").unlink()
        return "missing video"
    if case == "garbage video":
        (rec / "video.avi").write_bytes(b"\x00garbage" * 500)
        return "video.avi: OpenCV cannot open it"
    if case == "meta not json":
        (rec / "meta.json").write_text("{roi_px: [1, 2")
        return "meta.json: not valid JSON"
    if case == "meta lacks roi":
        meta = json.loads((rec / "meta.json").read_text())
        del meta["roi_px"]
        (rec / "meta.json").write_text(json.dumps(meta))
        return "meta.json: missing required key 'roi_px'"
    if case == "meta mistyped":
        meta = json.loads((rec / "meta.json").read_text())
        meta["workspace_mm"] = "100x70"
        (rec / "meta.json").write_text(json.dumps(meta))
        return "meta.json: key 'workspace_mm'"
    if case == "bad truth row":
        lines = (rec / "truth.csv").read_text().splitlines()
        lines[4] = "0.1,3,1,abc,2,3"
        (rec / "truth.csv").write_text("\n".join(lines) + "\n")
        return "truth.csv: line 5: column 'x_mm': 'abc' is not a number"
    if case == "wrong frame size":
        meta = json.loads((rec / "meta.json").read_text())
        meta["frame_size"] = [800, 600]
        (rec / "meta.json").write_text(json.dumps(meta))
        return "key 'frame_size' is [800, 600] but video.avi is 640x480"
    raise AssertionError(case)


@pytest.mark.parametrize("case", ["no video", "garbage video", "meta not json", "meta lacks roi",
                                  "meta mistyped", "bad truth row", "wrong frame size"])
def test_bad_input_is_one_line_without_traceback(blob_recording: Path, tmp_path: Path, case):
    expected = _break(blob_recording, case)
    proc = subprocess.run(
        [sys.executable, "-m", "fydpad.cli", "track", str(blob_recording),
         "--out", str(tmp_path / "t.csv")],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert expected in lines[0]
    assert str(blob_recording) in lines[0]  # the file is named with its path


def test_missing_recording_dir(tmp_path: Path, capsys):
    assert main(["track", str(tmp_path / "nope"), "--out", str(tmp_path / "t.csv")]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_camera_that_does_not_exist_is_named(tmp_path: Path, capsys):
    # No camera runs here: a device path that does not exist stands for an unplugged camera.
    rc = main(["track", "--camera", "/dev/video-missing", "--out", str(tmp_path / "t.csv")])
    assert rc == 2
    assert "camera '/dev/video-missing'" in capsys.readouterr().err


def test_indentation_filled_only_with_ir(tmp_path: Path):
    from tests.conftest import write_blob_recording
    for with_ir in (True, False):
        rec = tmp_path / f"ir{with_ir}"
        write_blob_recording(rec, [None] * 12 + [(0.0, 0.0)] * 3 + [None], with_ir=with_ir)
        out = tmp_path / f"t{with_ir}.csv"
        assert main(["track", str(rec), "--out", str(out)]) == 0
        ind = read_track(out)["indentation_mm"]
        if with_ir:
            # Constant voltages: the fabric never moves, so the indentation is ~0 mm.
            assert np.all(np.isfinite(ind)) and np.abs(ind).max() < 0.5
        else:
            assert np.all(np.isnan(ind))
