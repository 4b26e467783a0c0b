"""The simulated UR controller (UR5e in MuJoCo) behind ur-rtde's contract, driven by the
real UR slave code (teleop.slaves.ur.URArm). The controller is a simulation of UR's
(its firmware cannot run here); the arm's dynamics are MuJoCo's on the Menagerie model."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the mujoco extra (pip install 'fydpad[mujoco]') is absent")

from teleop.config import SlaveConfig, TeleopConfig
from teleop.slaves import ArmFault
from teleop.slaves.ur import URArm
from teleop.slaves.ur_sim import JOINT_SPEED_RAD_S, connect_sim, unlock_protective_stop

ROOT = Path(__file__).resolve().parents[2]
HOME_MM = np.array([550.0, 0.0, 250.0])


class Clock:
    """The caller's clock, advanced by the test: the controller runs up to it."""

    def __init__(self) -> None:
        self.t_s = 0.0

    def __call__(self) -> float:
        return self.t_s


def _arm(lookahead_s: float = 0.05, gain: float = 600.0) -> tuple[URArm, Clock]:
    clock = Clock()
    cfg = SlaveConfig(ur_host="sim", ur_lookahead_s=lookahead_s, ur_gain=gain)
    arm = URArm(cfg, connect=lambda host, hz: connect_sim(hz, clock=clock))
    arm.start(HOME_MM)
    return arm, clock


def _servo_for(arm: URArm, clock: Clock, target_mm, seconds: float, log=None) -> None:
    for _ in range(round(seconds / 0.002)):
        clock.t_s += 0.002
        arm.servo(np.asarray(target_mm, float), clock.t_s)
        if log is not None:
            log.append((clock.t_s, arm.actual_mm(), np.array(arm.recv.getActualQ())))


def test_movel_reaches_the_pose_at_its_speed_and_holds_it_against_gravity():
    arm, clock = _arm()
    np.testing.assert_allclose(arm.actual_mm(), HOME_MM, atol=0.05)
    c = arm.ctrl.c
    t0 = c.t_sim_s
    goal = HOME_MM + np.array([60.0, -50.0, -30.0])
    assert arm.ctrl.moveL(arm._pose(goal), 0.1, 0.5)
    np.testing.assert_allclose(arm.actual_mm(), goal, atol=0.05)
    # 85 mm at 0.1 m/s, then the 0.3 s settle: the move took its time on the arm's clock.
    assert c.t_sim_s - t0 == pytest.approx(np.linalg.norm(goal - HOME_MM) / 100.0 + 0.3,
                                           abs=0.01)
    assert arm.ctrl.moveL(arm._pose(HOME_MM), 0.1, 0.5)
    _servo_for(arm, clock, HOME_MM, 1.0)
    np.testing.assert_allclose(arm.actual_mm(), HOME_MM, atol=0.05)  # no sag
    # The tool points down: the flange's z axis along -z of the base.
    rv = arm.recv.getActualTCPPose()[3:]
    from scipy.spatial.transform import Rotation

    np.testing.assert_allclose(Rotation.from_rotvec(rv).apply([0, 0, 1]), [0, 0, -1],
                               atol=1e-4)


def test_servol_ranges_raise_as_ur_rtde_does():
    ctrl, _ = connect_sim()
    pose = [0.5, 0.0, 0.3, 0.0, math.pi, 0.0]
    with pytest.raises(ValueError, match="lookahead"):
        ctrl.servoL(pose, 0.5, 0.5, 0.002, 0.01, 600)
    with pytest.raises(ValueError, match="gain"):
        ctrl.servoL(pose, 0.5, 0.5, 0.002, 0.1, 3000)
    with pytest.raises(RuntimeError, match="500 Hz"):
        connect_sim(125.0)


def _rise_time_s(lookahead_s: float) -> float:
    """Time for the TCP to cover 63 % of a 5 mm step in x."""
    arm, clock = _arm(lookahead_s=lookahead_s)
    log: list = []
    _servo_for(arm, clock, HOME_MM + np.array([5.0, 0.0, 0.0]), 1.0, log)
    t0 = log[0][0] - 0.002
    reached = [t for t, p, _ in log if p[0] - HOME_MM[0] >= 0.63 * 5.0]
    final = log[-1][1]
    np.testing.assert_allclose(final, HOME_MM + np.array([5.0, 0.0, 0.0]), atol=0.05)
    return reached[0] - t0


def test_lookahead_is_the_smoothing_time_constant():
    fast, slow = _rise_time_s(0.03), _rise_time_s(0.2)
    # First-order reference of time constant L plus the servo's own lag (about 30 ms).
    assert 0.03 < fast < 0.1
    assert 0.2 < slow < 0.3
    assert slow - fast == pytest.approx(0.17, abs=0.04)


def test_joint_speeds_stay_within_the_ur5e_limit():
    arm, clock = _arm(lookahead_s=0.03, gain=1000.0)
    log: list = []
    _servo_for(arm, clock, HOME_MM + np.array([100.0, 100.0, 0.0]), 1.0, log)
    q = np.array([entry[2] for entry in log])
    qd = np.abs(np.diff(q, axis=0)) / 0.002
    assert qd.max() <= JOINT_SPEED_RAD_S * 1.1
    assert qd.max() > 0.5 * JOINT_SPEED_RAD_S  # the limit was what bounded the move
    np.testing.assert_allclose(arm.actual_mm(), HOME_MM + np.array([100.0, 100.0, 0.0]), atol=0.1)


def test_protective_stop_holds_the_arm_and_the_slave_says_what_to_check():
    arm, clock = _arm()
    _servo_for(arm, clock, HOME_MM + np.array([20.0, 0.0, 0.0]), 0.05)
    arm.ctrl.triggerProtectiveStop()
    held = arm.actual_mm()
    with pytest.raises(ArmFault, match="protective stop on sim"):
        _servo_for(arm, clock, HOME_MM + np.array([20.0, 0.0, 0.0]), 0.01)
    assert arm.recv.isProtectiveStopped() and arm.recv.getSafetyMode() == 3
    for _ in range(250):  # half a second later the arm is where it stopped
        clock.t_s += 0.002
        assert arm.ctrl.servoL([*(HOME_MM / 1000).tolist(), 0, math.pi, 0], 0.5, 0.5, 0.002,
                               0.05, 600) is False
    assert float(np.linalg.norm(arm.actual_mm() - held)) < 1.0
    unlock_protective_stop(arm.ctrl.c)
    _servo_for(arm, clock, HOME_MM, 1.0)
    np.testing.assert_allclose(arm.actual_mm(), HOME_MM, atol=0.1)


def test_following_error_trips_a_protective_stop():
    """A joint held back (a collision) lags its reference: the controller stops the arm."""
    arm, clock = _arm()
    c = arm.ctrl.c
    c.model.jnt_range[0] = [-6.28, 6.28]
    c.data.qfrc_applied[:] = 0
    log: list = []
    with pytest.raises(ArmFault, match="protective stop"):
        for _ in range(500):
            c.data.xfrc_applied[c.model.body("wrist_3_link").id, :3] = [0.0, 0.0, -2000.0]
            _servo_for(arm, clock, HOME_MM, 0.002, log)
    assert "lags its reference" in c.stop_reason


def test_servostop_brings_the_arm_to_rest_short_of_the_target():
    arm, clock = _arm(lookahead_s=0.2)
    _servo_for(arm, clock, HOME_MM + np.array([100.0, 0.0, 0.0]), 0.1)
    arm.hold()  # servoStop
    for _ in range(250):
        clock.t_s += 0.002
        arm.recv.getActualTCPPose()
    stopped = arm.actual_mm()
    for _ in range(100):
        clock.t_s += 0.002
    assert float(np.linalg.norm(arm.actual_mm() - stopped)) < 0.05  # at rest
    assert stopped[0] - HOME_MM[0] < 60.0  # short of the 100 mm target


def test_close_stops_the_script_and_disconnects():
    arm, _ = _arm()
    ctrl = arm.ctrl
    arm.close()
    assert not ctrl.c.script_running and not ctrl.isConnected()
    assert ctrl.servoL([0.5, 0, 0.3, 0, math.pi, 0], 0.5, 0.5, 0.002, 0.05, 600) is False
    arm.close()  # twice is safe


def test_teleop_slave_cli_follows_a_stroke_on_the_simulated_ur(tmp_path):
    """`teleop slave --robot ur --ur-host sim` in its own process; the master streams a
    two-second stroke of the bundled circle's true finger over loopback."""
    from teleop.master import run_session
    from vision.recording import read_csv_columns
    from vision.state import FingerState

    report = tmp_path / "slave.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "teleop.cli", "slave", "--robot", "ur", "--ur-host", "sim",
         "--bind", "tcp://127.0.0.1:*", "--rt-priority", "0", "--duration", "15",
         "--report", str(report)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    try:
        line = proc.stdout.readline()
        assert "listening on" in line, line + proc.stderr.read()
        endpoint = line.split("listening on ")[1].split()[0]
        truth = read_csv_columns(ROOT / "recordings" / "circle" / "truth.csv",
                                 ("t_s", "contact", "x_mm", "y_mm", "indentation_mm"),
                                 empty_ok=("x_mm", "y_mm"))
        keep = (truth["t_s"] >= 3.0) & (truth["t_s"] < 5.0) & (truth["contact"] != 0)
        states = [FingerState(float(t), True, x, y, d) for t, x, y, d in zip(
            truth["t_s"][keep], truth["x_mm"][keep], truth["y_mm"][keep],
            truth["indentation_mm"][keep], strict=True)]
        cfg = TeleopConfig()
        cfg.link.rt_priority = 0
        session = run_session(states, endpoint, cfg, baseline=False)
    finally:
        proc.terminate()
        proc.wait(20)
    # That it follows, not how well (benchmarks/bench_ur_sim.py measures the MAE on an
    # idle machine): the arm sweeps the finger's x and y span, and passes within 2 mm of
    # nearly every finger sample within 0.3 s of it (lag-tolerant: a loaded machine
    # delays the slave's ticks).
    assert session.report["samples"] == len(states)
    t_slave, slave_mm = session.main.slave_log()
    t_master, master_mm, _ = session.main.arrays()
    stroke = t_slave >= t_master[0]  # the stroke, not the glide to its start
    for axis in (0, 1):
        assert np.ptp(slave_mm[stroke, axis]) == pytest.approx(np.ptp(master_mm[:, axis]),
                                                               rel=0.2)
    near = [np.min(np.linalg.norm(slave_mm[np.abs(t_slave - t) <= 0.3, :2] - m[:2], axis=1))
            <= 2.0 for t, m in zip(t_master, master_mm, strict=True)]
    assert np.mean(near) >= 0.9
    import json

    rep = json.loads(report.read_text())
    assert rep["robot"] == "ur" and rep["arm_faults"] == 0 and rep["accepted"] > 20
