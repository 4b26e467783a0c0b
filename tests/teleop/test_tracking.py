"""Tracking accuracy against ground truth, on analytic finger paths at
30 fps with 0.1 mm measurement noise, through the real slave loop, safety chain and the
PyBullet iiwa.

Virtual time (teleop.virtual) makes the accuracy figures the algorithm's and the arm's,
independent of the shared machine's load; test_live_session then runs the same chain
over a real loopback socket in real time.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from teleop.config import TeleopConfig
from teleop.master import run_session
from teleop.slave import SlaveThread
from teleop.trajectories import circle, finger_stream, lissajous, tapping
from teleop.virtual import simulate_session

CASES = {"circle": circle, "lissajous": lissajous, "tapping": tapping}


@pytest.fixture(scope="module")
def sessions():
    out = {}
    for name, make in CASES.items():
        states, truth = finger_stream(make(), 4.0, seed=3)
        out[name] = simulate_session(states, truth=truth)
    return out


@pytest.mark.parametrize("name", ["circle", "lissajous"])
def test_mae_meets_target_on_xy_paths(sessions, name):
    """MAE (eq. 6, no shift) <= 0.5 mm on every axis at 40 mm/s, against both the
    master's samples and the true finger path."""
    rep = sessions[name].report
    for key in ("mae_mm", "truth_mae_mm"):
        assert max(rep[key].values()) <= 0.5, (key, rep)


def test_tapping_xy_meets_target(sessions):
    rep = sessions["tapping"].report
    assert rep["mae_mm"]["x"] <= 0.5 and rep["mae_mm"]["y"] <= 0.5, rep


@pytest.mark.xfail(strict=True, reason="z MAE 0.55 mm vs 0.5 mm: a 30 fps touch-down at "
                   "80 mm/s is not predictable to 0.5 mm (docs/teleop.md)")
def test_tapping_depth_meets_target(sessions):
    assert sessions["tapping"].report["mae_mm"]["z"] <= 0.5


@pytest.mark.parametrize("name", list(CASES))
def test_prediction_beats_the_papers_condition(sessions, name):
    """The paper's condition (10 Hz master, hold), measured in the same run, is several
    times worse (>2.5x) on the moving axes; on taps it comes out near the paper's ~2-3 mm."""
    rep = sessions[name].report
    moving = ["z"] if name == "tapping" else ["x", "y"]
    for a in moving:
        assert rep["baseline_mae_mm"][a] > 2.5 * rep["mae_mm"][a], rep
    if name == "tapping":
        assert 1.5 <= rep["baseline_mae_mm"]["z"] <= 4.0, rep


def test_report_has_the_recording_format_keys(sessions, tmp_path):
    rep = sessions["circle"].report
    for k in ("mae_mm", "baseline_mae_mm", "lag_ms", "latency_ms", "samples", "dropped",
              "duration_s", "truth_mae_mm"):
        assert k in rep
    assert set(rep["mae_mm"]) == {"x", "y", "z"}
    assert set(rep["latency_ms"]) == {"p50", "p99"}
    assert rep["samples"] == 120 and rep["dropped"] == 0
    json.dumps(rep)
    sessions["circle"].plot(str(tmp_path / "fig11.png"), "circle")
    assert (tmp_path / "fig11.png").stat().st_size > 10_000


def test_sim_arm_moves_like_an_arm_not_a_teleport():
    """A 100 mm step in the target: the iiwa's joints take time (finite joint speed)."""
    from teleop.slaves.sim import SimArm
    arm = SimArm(joint_speed_rad_s=1.7)
    home = np.array([550.0, 0.0, 250.0])
    arm.start(home)
    try:
        target = home + np.array([0.0, 100.0, 0.0])
        t, reached = 0.0, None
        for _ in range(1000):
            t += 0.002
            arm.servo(target, t)
            if reached is None and np.linalg.norm(arm.actual_mm() - target) < 1.0:
                reached = t
        assert reached is not None and reached > 0.05
    finally:
        arm.close()


@pytest.mark.parametrize("reengage_mm_s", [300.0, 60.0])
def test_clutch_holds_xy_and_returns_to_surface_then_no_jump(reengage_mm_s):
    """Lift (contact 0): x, y held, depth back to the surface; a touch 10 mm away is
    approached within the configured re-engage speed (default 300 mm/s, the speed limit)
    and the acceleration limit, without overshoot: moving at the arm's limits, not
    jumping."""
    from teleop import protocol as P
    from teleop.virtual import simulate_session
    from vision.state import FingerState
    states = [FingerState(k / 30, True, 10.0, 0.0, 5.0) for k in range(15)]
    states += [FingerState.no_contact(k / 30) for k in range(15, 30)]
    states += [FingerState(k / 30, True, 20.0, 0.0, 2.0) for k in range(30, 60)]
    cfg = TeleopConfig()
    cfg.safety.reengage_speed_mm_s = reengage_mm_s
    s = simulate_session(states, cfg, baseline=False)
    t, _, _ = s.main.arrays()
    tl, sl = s.main.slave_log()
    lifted = (tl > t[20]) & (tl < t[29])
    np.testing.assert_allclose(sl[lifted, 0], 10.0, atol=0.3)
    np.testing.assert_allclose(sl[lifted, 2], 0.0, atol=0.3)
    ticks = [(st.t_slave_s, st.cmd_mm) for _, st in s.main.states if st.reason == P.REASON_TICK]
    tc = np.array([r[0] for r in ticks])
    cmd = np.array([r[1] for r in ticks])
    after = tc > t[30]
    v = np.diff(cmd[after, 0]) / np.diff(tc[after])
    assert 0.5 * reengage_mm_s <= v.max() <= reengage_mm_s * 1.01
    acc = np.abs(np.diff(v)) / np.diff(tc[after])[1:]
    assert acc.max() <= cfg.safety.max_accel_mm_s2 * 1.01
    # Where x and the depth must both slow down beyond the limit they share it, so x may
    # pass by ~0.1 mm (0.11 measured; 0.8 with the vector scaled as a whole).
    assert cmd[after, 0].max() <= 20.0 + 0.15
    assert abs(sl[-1, 0] - 20.0) < 0.3


def test_a_deep_touch_nearby_is_reached_without_overshoot_or_diving():
    """A touch 5 mm from the held point and already 8 mm deep (the depth moves more than
    x): the command does not pass the new point in x by more than braking shared with
    the depth allows, and in transit the tool never goes
    deeper than the finger was measured (the touch-down's extrapolation would dive first),
    within the acceleration limit; the PyBullet arm follows it. Before (the acceleration
    vector scaled as a whole): x passed by 0.4 mm at 150 mm/s, 0.8 mm at 300 mm/s."""
    from teleop import protocol as P
    from vision.state import FingerState
    states = [FingerState(k / 30, True, 10.0, 0.0, 5.0) for k in range(15)]
    states += [FingerState.no_contact(k / 30) for k in range(15, 30)]
    states += [FingerState(k / 30, True, 15.0, 0.0, 8.0) for k in range(30, 60)]
    cfg = TeleopConfig()
    s = simulate_session(states, cfg, baseline=False)
    t, _, _ = s.main.arrays()
    ticks = [(st.t_slave_s, st.cmd_mm, st.actual_mm) for _, st in s.main.states
             if st.reason == P.REASON_TICK]
    tc = np.array([r[0] for r in ticks])
    cmd = np.array([r[1] for r in ticks])
    act = np.array([r[2] for r in ticks])
    after = tc > t[30]
    arrived = np.flatnonzero(after & (np.linalg.norm(cmd - [15.0, 0.0, 8.0], axis=1) < 0.2))[0]
    transit = after & (np.arange(tc.size) <= arrived)
    # x shares the braking with the depth (0.09 mm measured; 0.8 with the vector scaled
    # as a whole, test_safety.py has why the depth keeps its share).
    assert cmd[after, 0].max() <= 15.0 + 0.15 and act[after, 0].max() <= 15.0 + 0.2
    assert cmd[transit, 2].max() <= 8.0 + 0.01 and act[transit, 2].max() <= 8.0 + 0.05
    v = np.diff(cmd[after], axis=0) / np.diff(tc[after])[:, None]
    acc = np.linalg.norm(np.diff(v, axis=0), axis=1) / np.diff(tc[after])[1:]
    assert acc.max() <= cfg.safety.max_accel_mm_s2 * 1.01
    np.testing.assert_allclose(act[-1], [15.0, 0.0, 8.0], atol=0.3)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["circle", "lissajous", "tapping"])
def test_bundled_recording_meets_the_target_in_virtual_time(name):
    """`fydpad demo`'s chain (video tracked, IR indentation with the bundled device's
    calibration, PyBullet slave) in virtual time: MAE (eq. 6, no shift) <= 0.5 mm on
    every axis. Before the re-engage at the speed limit and the three-model IMM:
    Lissajous z 0.51, tapping y 0.62 (docs/teleop.md; fresh seeds are in the doc)."""
    from fydpad.bundled import bundled_recording, recordings_dir
    from fydpad.config import load_config
    from fydpad.teleop_run import recording_states, truth_rows
    from vision.recording import PadRecording
    cfg = load_config(recordings_dir() / "device.toml")
    rec = PadRecording(bundled_recording(name))
    s = simulate_session(recording_states(rec, cfg), cfg.teleop, truth=truth_rows(rec),
                         baseline=False)
    assert max(s.report["mae_mm"].values()) <= 0.5, s.report


@pytest.mark.slow
def test_live_session_over_loopback():
    """The same chain in real time over a real loopback socket (the demo's path): samples
    arrive and are scored, prediction beats the paper's condition. Accuracy bounds are
    the virtual test's (the live figure is benchmarks/bench_tracking.py's). Master and
    slave are threads of this process: a loaded machine may starve both past the 0.2 s
    stale age or the 250 ms watchdog, which would drop samples and hold by design (their
    own tests), so here both are 5 s and every sample of the pass must be accepted."""
    states, truth = finger_stream(circle(), 3.0, seed=5)
    cfg = TeleopConfig()
    cfg.safety.max_age_s = cfg.safety.watchdog_s = 5.0
    with SlaveThread(cfg) as sl:
        s = run_session(states, sl.endpoint, truth=truth)
    rep = s.report
    assert rep["samples"] == 90 and rep["dropped"] == 0, rep
    assert rep["mae_mm"]["x"] < rep["baseline_mae_mm"]["x"], rep
    assert rep["latency_ms"]["p50"] is not None


def test_watchdog_holds_then_resumes_without_a_jump():
    """The master goes silent for 0.6 s while the finger moves 20 mm: the slave holds
    (status WATCHDOG_HOLD, no motion), then glides to the finger at the resume speed."""
    from teleop import protocol as P
    from vision.state import FingerState
    states = [FingerState(k / 30, True, 10.0, 0.0, 3.0) for k in range(30)]
    states += [FingerState(k / 30, True, 30.0, 0.0, 3.0) for k in range(48, 90)]
    cfg = TeleopConfig()
    s = simulate_session(states, cfg, baseline=False)
    ticks = [(st.t_slave_s, st.status, st.cmd_mm) for _, st in s.main.states if st.reason == 0]
    t = np.array([r[0] for r in ticks])
    cmd = np.array([r[2] for r in ticks])
    status = np.array([r[1] for r in ticks])
    t_last = s.main.t0_s + 29 / 30
    t_back = s.main.t0_s + 48 / 30
    held = (t > t_last + 0.26) & (t < t_back)
    assert held.any() and np.all(status[held] == P.STATUS_WATCHDOG_HOLD)
    np.testing.assert_allclose(cmd[held, 0], 10.0, atol=0.05)
    after = t >= t_back
    v = np.abs(np.diff(cmd[after, 0]) / np.diff(t[after]))
    assert v.max() <= cfg.safety.resume_speed_mm_s * 1.01
    assert abs(cmd[-1, 0] - 30.0) < 0.3


def test_finger_to_the_right_moves_the_simulated_arm_to_its_configured_right():
    """Through the whole slave (mapping, limits, IK, physics): with the workspace rotated
    90 deg about the robot's z axis, a finger 20 mm to the user's right puts the iiwa's
    tool 20 mm along the robot's +y, at the same x and height."""
    from teleop.slaves.sim import SimArm
    from vision.state import FingerState

    class Spy(SimArm):
        last = None

        def actual_mm(self):
            Spy.last = super().actual_mm()
            return Spy.last

    cfg = TeleopConfig()
    cfg.mapping.rpy_deg = (0.0, 0.0, 90.0)
    states = [FingerState(k / 30, True, 20.0, 0.0, 0.0) for k in range(30)]
    simulate_session(states, cfg, baseline=False, arm=Spy(lag_s=0.002))
    np.testing.assert_allclose(Spy.last, np.add(cfg.mapping.origin_mm, [0.0, 20.0, 0.0]),
                               atol=0.3)
