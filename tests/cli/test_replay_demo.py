"""`fydpad replay` against a real `teleop slave` process, and `fydpad demo`, over loopback.

These prove the chain runs end to end over real sockets and writes the report of
docs/recording_format.md, with the simulated arm following the finger (errors far below the
workspace's size). The accuracy targets themselves are checked in virtual time, where a
shared machine's scheduling cannot blur them (tests/teleop/test_tracking.py).
"""

from __future__ import annotations

import json
import socket
from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main
from tests.conftest import write_blob_recording
from tests.teleop.helpers import start_slave

REPORT_KEYS = {"mae_mm", "baseline_mae_mm", "lag_ms", "latency_ms", "samples", "dropped",
               "duration_s", "truth_mae_mm"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def stroke_rec(tmp_path_factory) -> Path:
    rec = tmp_path_factory.mktemp("replay") / "stroke"
    t = np.arange(75) / 30.0
    pos = [None] * 8 + [(-20 + 15 * s, 10 * np.sin(2 * s)) for s in t[:60]] + [None] * 7
    write_blob_recording(rec, pos)
    return rec


def test_replay_against_a_slave_process(stroke_rec: Path, tmp_path: Path, capsys):
    port = free_port()
    endpoint = f"tcp://127.0.0.1:{port}"
    # Started once it says it listens (a loaded machine may take seconds to import it).
    slave, _ = start_slave("--robot", "sim", bind=endpoint, timeout_s=120.0)
    try:
        report_path = tmp_path / "report.json"
        rc = main(["replay", str(stroke_rec), "--teleop", endpoint, "--report",
                   str(report_path), "--plot", str(tmp_path / "fig11.png")])
        assert rc == 0
    finally:
        slave.terminate()
        slave.wait(timeout=20)
    report = json.loads(report_path.read_text())
    assert REPORT_KEYS <= set(report)
    assert report["samples"] > 50
    for axis in "xyz":
        assert report["mae_mm"][axis] < 5.0  # a broken chain is off by tens of mm
    assert (tmp_path / "fig11.png").stat().st_size > 10_000
    assert "MAE" in capsys.readouterr().out


def test_replay_without_a_slave_is_one_line(stroke_rec: Path, tmp_path: Path, capsys):
    endpoint = f"tcp://127.0.0.1:{free_port()}"
    rc = main(["replay", str(stroke_rec), "--teleop", endpoint, "--report",
               str(tmp_path / "r.json"), "--no-baseline"])
    assert rc == 2
    assert "no slave answered" in capsys.readouterr().err


def test_demo_on_a_bundled_recording(tmp_path: Path, capsys, monkeypatch):
    """The demo explains itself: it names where it writes, writes its plot there by default
    (titled with the recording and its MAE), ends with the table and one sentence."""
    monkeypatch.chdir(tmp_path)
    rc = main(["demo", "--recordings", "tapping"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "plots and reports go to fydpad-demo/" in out
    report = json.loads((tmp_path / "fydpad-demo" / "tapping.json").read_text())
    assert REPORT_KEYS <= set(report)
    assert report["mae_mm"]["z"] < 10.0  # the arm follows the taps (they reach 15-45 mm)
    assert (tmp_path / "fydpad-demo" / "tapping.png").stat().st_size > 10_000
    assert "tapping: MAE" in out
    table = out[out.index("recording  this run"):].splitlines()
    assert "paper's condition" in table[0] and "paper's figure" in table[0]
    row = table[1].split()
    assert row[0] == "tapping"
    mae = report["mae_mm"]
    assert row[1:6] == [f"{mae['x']:.2f}", "/", f"{mae['y']:.2f}", "/", f"{mae['z']:.2f}"]
    assert "~3 / ~3 / ~3" in table[1]  # Bianchi et al. 2015, section IV-B
    assert f"{report['baseline_mae_mm']['z']:.2f}" in table[1]
    assert "dominate" in table[2]  # the sentence under the table
    if "truth_breakdown_mm" in report:
        assert "largest part" in out
