"""UR safety on every exit path: `teleop slave --robot ur` in a real process, the UR
controller replaced by the fake of ur-rtde's contract (tests/teleop/fake_rtde.py; no
controller runs here). Whenever the slave stops the robot, servoStop then stopScript are
called (ur-rtde: servoStop "stops servo mode and decelerates the robot", stopScript
"terminates the script on the controller"), and servoL never after them."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

from teleop import protocol as P

from .helpers import ENV, REPO, Master, stop, wait_for


def start_ur_slave(tmp_path, fault: str, *args: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.teleop.ur_slave_proc", str(tmp_path / "calls.json"),
         fault, "--bind", "tcp://127.0.0.1:*", "--rt-priority", "0", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV, cwd=REPO)
    line = proc.stdout.readline()
    if "listening on" not in line:
        proc.kill()
        raise RuntimeError(f"UR slave did not start: {line} {proc.stderr.read()}")
    return proc, line.split("listening on ")[1].split()[0]


def calls_after_streaming(tmp_path) -> list[str]:
    calls = json.loads((tmp_path / "calls.json").read_text())
    assert calls.count("servoL") > 20, calls[-5:]  # it was streaming
    return calls


def assert_stopped(calls: list[str]) -> None:
    """servoStop and stopScript once each, in that order, no servoL after them."""
    assert calls.count("stopScript") == 1
    i, j = calls.index("stopScript") - 1, calls.index("stopScript")
    assert calls[i] == "servoStop", calls[-6:]
    assert "servoL" not in calls[j:]


def streamed(ep: str, n_ticks: int = 50) -> Master:
    m = Master(ep, x_mm=5.0)
    assert wait_for(lambda: len(m.ticks()) >= n_ticks, 60.0)
    return m


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl_c", "sigterm"])
def test_a_signal_stops_the_robot(tmp_path, sig):
    """Ctrl-C (SIGINT) and SIGTERM mid-stream: the slave exits 0 having stopped the robot."""
    proc, ep = start_ur_slave(tmp_path, "none")
    m = streamed(ep)
    try:
        proc.send_signal(sig)
        proc.communicate(timeout=20)
        assert proc.returncode == 0
    finally:
        m.stop()
    assert_stopped(calls_after_streaming(tmp_path))


@pytest.mark.parametrize("fault, code", [("loop", 1), ("link", 1)],
                         ids=["fault_in_the_loop", "link_fault"])
def test_a_fault_stops_the_robot_and_the_slave_says_why(tmp_path, fault, code):
    """An exception inside the control loop, or the link socket failing (ZMQError):
    the slave exits non-zero with the reason on stderr, the robot stopped."""
    proc, ep = start_ur_slave(tmp_path, fault)
    m = Master(ep, x_mm=5.0)
    try:
        _, err = proc.communicate(timeout=30)
    finally:
        m.stop()
    assert proc.returncode == code, err
    assert "stopped the robot on a fault" in err and "injected" in err
    assert_stopped(calls_after_streaming(tmp_path))


def test_a_protective_stop_mid_stream_stops_the_robot_and_the_slave_reports_fault(tmp_path):
    """The controller reports a protective stop while streaming: the slave stops the robot
    at once (not only at exit), keeps answering with status FAULT, and exits 0 on Ctrl-C."""
    proc, ep = start_ur_slave(tmp_path, "pstop")
    m = Master(ep, x_mm=5.0)
    try:
        assert wait_for(lambda: any(s.status == P.STATUS_FAULT for s in m.ticks()), 30.0)
        stop(proc)
        assert proc.returncode == 0
    finally:
        m.stop()
    assert_stopped(calls_after_streaming(tmp_path))


def test_an_operator_hold_past_its_timeout_stops_the_robot(tmp_path):
    """The owner's samples carry the operator hold for longer than
    safety.operator_hold_stop_s (0.5 s here): the slave stops the robot and answers with
    status "stopped" until it is restarted; it does not exit."""
    cfg = tmp_path / "slave.toml"
    cfg.write_text("[safety]\noperator_hold_stop_s = 0.5\n")
    proc, ep = start_ur_slave(tmp_path, "none", "--config", str(cfg))
    m = streamed(ep)
    try:
        m.operator_hold = True
        assert wait_for(lambda: any(s.status == P.STATUS_OPERATOR_HOLD for s in m.ticks()),
                        20.0)
        assert wait_for(lambda: m.ticks()[-1].status == P.STATUS_STOPPED, 60.0)
        assert proc.poll() is None
        stop(proc)
        assert proc.returncode == 0
    finally:
        m.stop()
    assert_stopped(calls_after_streaming(tmp_path))
