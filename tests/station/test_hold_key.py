"""The operator hold from `fydpad run`'s terminal, end to end: the real command with its
standard input on a pseudo-terminal; ``h`` holds, the space bar releases, both recorded
in the session's events.csv; the terminal's mode is restored after."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import termios
import time
from pathlib import Path


def _wait_for(path: Path, text: str, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if text in path.read_text():
            return True
        time.sleep(0.1)
    return False


def test_h_holds_and_space_releases_from_the_terminal(tmp_path: Path):
    master, slave = os.openpty()
    before = termios.tcgetattr(slave)
    err_path = tmp_path / "err.txt"
    rec = tmp_path / "s"
    with err_path.open("w") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "fydpad.cli", "run", "--synthetic", "hover",
             "--duration", "120", "--no-realtime", "--record", str(rec), "--no-video"],
            stdin=slave, stdout=subprocess.DEVNULL, stderr=err, cwd=tmp_path)
    try:
        assert _wait_for(err_path, "press h or space to hold", 180), err_path.read_text()
        # The recording is open once the loops run: events.csv exists.
        deadline = time.monotonic() + 180
        while not (rec / "events.csv").exists():
            assert time.monotonic() < deadline and proc.poll() is None, err_path.read_text()
            time.sleep(0.1)
        os.write(master, b"x")  # not a hold key: nothing happens
        os.write(master, b"h")
        deadline = time.monotonic() + 60
        while "hold,key" not in (rec / "events.csv").read_text():
            assert time.monotonic() < deadline, "h did not hold"
            time.sleep(0.1)
        os.write(master, b" ")
        deadline = time.monotonic() + 60
        while "release,key" not in (rec / "events.csv").read_text():
            assert time.monotonic() < deadline, "space did not release"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 0, err_path.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    rows = (rec / "events.csv").read_text().splitlines()
    assert [r.split(",")[1:] for r in rows[1:]] == [["hold", "key"], ["release", "key"]]
    # The terminal is back in the mode it had (cbreak undone).
    assert termios.tcgetattr(slave) == before
    os.close(master)
    os.close(slave)
