"""`fydpad run --teleop` towards a slave that is missing, dies, or has no keys to match:
the station runs on safely, ends with one line saying what the link did, exits 3. The
slave is the real `teleop slave` process on loopback."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time

import pytest

from tests.cli.test_getting_started import free_port
from tests.teleop.helpers import ENV, REPO, start_slave

CIRCLE = str(REPO / "recordings" / "circle")


def master(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fydpad.cli", "run", "--replay", CIRCLE,
                             *args], cwd=REPO, env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def test_a_slave_that_never_answers_ends_the_run_with_a_line_and_status_3():
    port = free_port()  # nobody listens there
    proc = master("--teleop", f"127.0.0.1:{port}", "--duration", "2")  # HOST:PORT is tcp
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 3, err
    assert "station ran" in out  # the station itself ran to the end
    assert f"link 127.0.0.1:{port}: no slave ever answered" in err
    assert "Traceback" not in err


@pytest.mark.slow
def test_a_slave_lost_during_the_run_is_reported_and_the_station_runs_on(tmp_path):
    slave, endpoint = start_slave("--robot", "sim", "--curve", "off")
    track = tmp_path / "rec" / "track.csv"
    proc = master("--teleop", endpoint, "--duration", "60", "--record", str(tmp_path / "rec"))
    try:
        t_end = time.monotonic() + 60
        while time.monotonic() < t_end and proc.poll() is None and (
                not track.is_file() or track.stat().st_size < 2000):
            time.sleep(0.1)  # the station is running (and streaming) once it records
        time.sleep(1.0)
    finally:
        slave.kill()
        slave.communicate(timeout=10)
    time.sleep(2.5)  # the station runs on without its slave
    proc.send_signal(signal.SIGINT)  # Ctrl-C: stops safely
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 3, err
    # At least the kill; a slave starved by a loaded machine may also have gone quiet
    # past the watchdog before it (each silence is counted, never fatal).
    assert re.search(r"the slave went silent [1-9][0-9]* time\(s\)", err), err
    assert "station ran" in out


def test_missing_keys_are_one_line_naming_the_command_that_makes_them(tmp_path):
    proc = master("--teleop", "10.0.0.5:5555", "--keys", str(tmp_path / "none"),
                  "--duration", "1")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"teleop keys generate {tmp_path / 'none'}" in err


def test_the_status_line_shows_a_dash_for_values_not_known_yet():
    from fydpad.commands.run import format_status

    nan = float("nan")
    line = format_status({"frames": 3, "contact": True, "x_mm": nan, "y_mm": 1.0,
                          "indentation_mm": nan, "force_n": nan, "measured_n_per_mm": nan,
                          "requested_n_per_mm": nan, "render": {"rate_hz": nan},
                          "vision": {}})
    assert "nan" not in line.lower()
    assert "k -/- N/mm" in line and "z     - mm" in line and "y   +1.0 mm" in line
