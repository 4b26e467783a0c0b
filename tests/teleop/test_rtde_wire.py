"""The real ur-rtde RTDEReceiveInterface (from the installed wheel) against a tiny RTDE
server on 127.0.0.2:30004: proves our reading of the protocol (version negotiation,
controller version, output recipe, start, data packages) matches what ur-rtde speaks, and
that getActualTCPPose returns the pose the controller sends."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from .helpers import ENV, REPO
from .rtde_server import RTDEServer

pytest.importorskip("rtde_receive")


def test_rtde_receive_reads_poses_from_a_wire_level_server():
    try:
        server = RTDEServer("127.0.0.2", 30004)
    except OSError as e:
        pytest.skip(f"127.0.0.2:30004 unavailable ({e}): RTDEReceiveInterface has no port arg")
    with server:
        server.pose = [0.55, -0.01, 0.25, 0.0, 3.14159, 0.0]
        try:
            out = subprocess.run([sys.executable, str(REPO / "tests/teleop/rtde_client_proc.py"),
                                  "127.0.0.2"], capture_output=True, text=True, timeout=20,
                                 env=ENV, cwd=REPO)
        except subprocess.TimeoutExpired as e:
            pytest.fail(f"RTDEReceiveInterface hung; server saw {server.log[:20]}: {e}")
    assert out.returncode == 0, out.stderr + out.stdout
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert "actual_TCP_pose" in server.requested
    assert server.log[:2] == ["V", "v"] and "O" in server.log and "S" in server.log
    assert res["connected"] and not res["pstop"]
    for pose in res["poses"]:
        assert pose == pytest.approx(server.pose)
