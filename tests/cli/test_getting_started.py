"""docs/getting_started.md, followed literally: its command blocks run as a slave and a
master process on loopback, with CurveZMQ forced on and the keys made by the page's own
`teleop keys generate`.

What the test changes, and only that: `SLAVE` becomes 127.0.0.1, the ports 5555 and 8080
become free ones, `scp SLAVE:FILE` becomes a copy from the slave's folder, `pip install`
is skipped (the package under test is already importable), and `teleop`/`fydpad` run as
``python -m teleop.cli`` / ``python -m fydpad.cli`` from this checkout.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "getting_started.md"
ENV = {**os.environ, "PYTHONPATH": str(REPO)}
pytestmark = pytest.mark.slow


def page_blocks(text: str) -> list[tuple[str, list[str]]]:
    """The page's ```bash blocks as (where, commands): where is the block's first line,
    `# on the slave`, `# on the master` or `# on both`."""
    blocks = []
    for body in re.findall(r"```bash\n(.*?)```", text, re.S):
        lines = [ln.strip() for ln in body.strip().splitlines() if ln.strip()]
        where = re.fullmatch(r"# on (the slave|the master|both)", lines[0])
        assert where, f"a command block of {PAGE.name} does not say where it runs: {lines[0]!r}"
        blocks.append((where.group(1).replace("the ", ""), lines[1:]))
    return blocks


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def localise(command: str, ports: dict[str, str]) -> list[str]:
    """The page's command with loopback for SLAVE and free ports; the program as a module."""
    for page_port, port in ports.items():
        command = command.replace(f":{page_port}", f":{port}")
        command = re.sub(rf"(--web ){page_port}\b", rf"\g<1>{port}", command)
    argv = shlex.split(command.replace("SLAVE:", "127.0.0.1:"))
    program = {"teleop": "teleop.cli", "fydpad": "fydpad.cli"}[argv[0]]
    return [sys.executable, "-m", program, *argv[1:]]


def test_the_getting_started_page_runs_a_tele_operation_with_curve_on(tmp_path):
    blocks = page_blocks(PAGE.read_text(encoding="utf-8"))
    slave_dir, master_dir = tmp_path / "slave", tmp_path / "master"
    for d in (slave_dir, master_dir):
        d.mkdir()
        (d / "recordings").symlink_to(REPO / "recordings")  # the clone's bundled recordings
    ports = {"5555": str(free_port()), "8080": str(free_port())}
    slave = None
    ran = []
    try:
        for where, commands in blocks:
            for command in commands:
                if command.startswith("pip install"):
                    continue
                cwd = slave_dir if where == "slave" else master_dir
                if command.startswith("mkdir -p "):
                    (cwd / command.split()[-1]).mkdir(parents=True, exist_ok=True)
                elif command.startswith("scp "):
                    *sources, target = shlex.split(command)[1:]
                    for src in sources:
                        assert src.startswith("SLAVE:"), src
                        shutil.copy(slave_dir / src.removeprefix("SLAVE:"), cwd / target)
                elif command.startswith("teleop slave"):
                    assert "--curve on" in command  # the page forces CurveZMQ on
                    slave = subprocess.Popen(localise(command, ports), cwd=cwd, env=ENV,
                                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                             text=True)
                    line = ""
                    t_end = time.monotonic() + 60
                    while "listening on" not in line and time.monotonic() < t_end:
                        line = slave.stdout.readline()
                        assert line or slave.poll() is None, slave.stderr.read()
                    assert "(CurveZMQ)" in line, line
                elif command.startswith("fydpad run"):
                    master = subprocess.Popen(localise(command, ports), cwd=cwd, env=ENV,
                                              stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                              text=True)
                    url = None
                    t_end = time.monotonic() + 90
                    while url is None and time.monotonic() < t_end:
                        line = master.stderr.readline()
                        assert line or master.poll() is None, "master ended before its web view"
                        if line.startswith("web view: "):
                            url = line.split()[-1]
                    with urllib.request.urlopen(url, timeout=10) as page:  # the web view is up
                        assert page.status == 200
                    out, err = master.communicate(timeout=180)
                    assert master.returncode == 0, err  # 3 would mean the link failed
                    assert "station ran 300 frames" in out, out
                else:
                    proc = subprocess.run(localise(command, ports), cwd=cwd, env=ENV,
                                          capture_output=True, text=True, timeout=240)
                    assert proc.returncode == 0, f"{command}\n{proc.stderr}"
                ran.append(command.split()[:2])
        assert [c[:2] for c in ran] == [
            ["teleop", "keys"], ["mkdir", "-p"], ["scp", "SLAVE:teleop_keys/server.key"],
            ["teleop", "slave"], ["fydpad", "run"], ["fydpad", "replay"]]
        # The keys the page made, where the page put them: the master holds no server secret.
        assert sorted(p.name for p in (master_dir / "teleop_keys").iterdir()) == [
            "client.key", "client.key_secret", "server.key"]
        report = json.loads((master_dir / "report.json").read_text())
        assert report["samples"] == 300 and report["dropped"] == 0
        # The robot followed the recorded finger: well inside the paper's ~3 mm.
        assert max(report["mae_mm"].values()) < 3.0, report["mae_mm"]
        assert (master_dir / "report.png").stat().st_size > 10_000
        for name in ("video.avi", "track.csv", "ir.csv", "meta.json"):
            assert (master_dir / "first-recording" / name).is_file(), name
    finally:
        if slave is not None and slave.poll() is None:
            slave.send_signal(signal.SIGINT)  # the page's Ctrl-C
            slave.communicate(timeout=30)
    slave_report = json.loads((slave_dir / "slave.json").read_text())
    assert slave_report["received"] >= 2 * 300  # the live run and the report's pass
