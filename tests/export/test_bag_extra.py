"""Without the ros extra, ``fydpad export bag`` and ``fydpad run --bag`` are one clear line,
exit 2 (this test needs no rosbags: it hides it when it is installed)."""

from __future__ import annotations

import sys
from pathlib import Path

from fydpad.cli import main

RECORDING = Path(__file__).resolve().parents[2] / "recordings" / "tapping"


def test_export_without_rosbags_says_what_to_install(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "rosbags", None)
    assert main(["export", "bag", str(RECORDING), "--out", str(tmp_path / "bag")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'fydpad[ros]'" in err[0]
    assert not (tmp_path / "bag").exists()
    assert main(["run", "--replay", str(RECORDING), "--record", str(tmp_path / "rec"),
                 "--bag", str(tmp_path / "bag")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'fydpad[ros]'" in err[0]
    assert not (tmp_path / "rec").exists()  # refused before the station started


def test_run_bag_needs_record(capsys, tmp_path):
    assert main(["run", "--replay", str(RECORDING), "--bag", str(tmp_path / "bag")]) == 2
    assert "--bag needs --record DIR" in capsys.readouterr().err
