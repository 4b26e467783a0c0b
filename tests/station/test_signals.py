"""The station under a service manager's signals, with real processes: SIGTERM stops it
safely like Ctrl-C, and a killed station never leaves its render process running."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import write_blob_recording
from vision.recording import read_track


@pytest.fixture(scope="module")
def long_rec(tmp_path_factory) -> Path:
    rec = tmp_path_factory.mktemp("sig") / "rec"
    write_blob_recording(rec, [None] * 4 + [(10 * np.cos(k / 9), 8 * np.sin(k / 9))
                                            for k in range(250)])
    return rec


def children(pid: int) -> list[int]:
    out = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True).stdout
    return [int(p) for p in out.split()]


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead for our purpose: check its state.
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


def start_station(rec: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fydpad.cli", "run", "--replay", str(rec),
                             "--record", str(out), "--no-realtime"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_render_child(proc: subprocess.Popen, out: Path, timeout_s: float = 180.0) -> int:
    """The render process (multiprocessing's spawn child), once frames are flowing (a
    bound against a hang, not a speed: a loaded machine starts the station slowly)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        kids = [k for k in children(proc.pid)
                if "spawn_main" in Path(f"/proc/{k}/cmdline").read_text(errors="ignore")]
        if kids and (out / "track.csv").exists():
            return kids[0]
        time.sleep(0.1)
    raise AssertionError("the station did not start its render process")


def test_sigterm_stops_safely_and_keeps_the_recording(long_rec: Path, tmp_path: Path):
    out = tmp_path / "session"
    proc = start_station(long_rec, out)
    render = wait_for_render_child(proc, out)
    deadline = time.monotonic() + 180  # some frames tracked (flushed every 0.5 s)
    while len((out / "track.csv").read_text().splitlines()) < 7:
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.1)
    seen = len((out / "track.csv").read_text().splitlines()) - 1
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "stopping" in err
    assert not alive(render)
    rows = len(read_track(out / "track.csv")["t_s"])
    assert seen <= rows < 254  # stopped part-way, what it had is kept


def test_a_killed_station_does_not_leave_its_render_process(long_rec: Path, tmp_path: Path):
    out = tmp_path / "session"
    proc = start_station(long_rec, out)
    render = wait_for_render_child(proc, out)
    proc.kill()
    proc.wait(timeout=10)
    deadline = time.monotonic() + 10
    while alive(render) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(render), "render process still running after its station was killed"
