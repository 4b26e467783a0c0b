"""`fydpad run --replay` for longer than the recording: it holds on the last frame until
--duration, or with --loop starts the recording again (frames, IR and force)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main
from tests.conftest import write_blob_recording
from vision.recording import read_track


@pytest.fixture
def short_rec(tmp_path: Path) -> Path:
    rec = tmp_path / "rec"
    write_blob_recording(rec, [None] * 3 + [(-20.0 + 2 * i, 5.0) for i in range(12)])
    return rec  # 15 frames at 30 fps: 0.5 s, the last one a contact at x = 2 mm


def run(rec: Path, out: Path, *extra: str) -> dict:
    assert main(["run", "--replay", str(rec), "--as-fast-as-possible", "--record", str(out),
                 *extra]) == 0
    return read_track(out / "track.csv")


def test_without_loop_the_station_holds_on_the_last_frame(short_rec, tmp_path):
    track = run(short_rec, tmp_path / "held", "--duration", "1.5")
    assert track["t_s"][-1] == pytest.approx(1.5, abs=1 / 30)  # ran the whole --duration
    held = track["t_s"] >= 0.5
    assert held.sum() >= 28
    assert np.all(track["contact"][held] == 1)
    assert np.allclose(track["x_mm"][held], track["x_mm"][14], atol=0.01)  # the last frame


def test_with_loop_the_recording_starts_again(short_rec, tmp_path):
    track = run(short_rec, tmp_path / "looped", "--duration", "1.5", "--loop")
    assert track["t_s"][-1] == pytest.approx(1.5, abs=1 / 30)
    first, second = track["x_mm"][:15], track["x_mm"][15:30]
    np.testing.assert_allclose(second, first, atol=0.01, equal_nan=True)  # the same again
    assert np.all(track["contact"][15:18] == 0)  # the lifted start of the second pass
    ir = np.loadtxt(tmp_path / "looped" / "ir.csv", delimiter=",", skiprows=1)
    assert ir[-1, 0] > 1.4  # the IR replayed too


def test_loop_needs_a_duration(short_rec, capsys):
    assert main(["run", "--replay", str(short_rec), "--loop"]) == 2
    assert "--loop needs --duration" in capsys.readouterr().err
