"""The UR slave against a fake that copies ur-rtde's contract, and that contract checked
against the installed wheel's pybind11 signatures."""

from __future__ import annotations

import inspect
import re

import numpy as np
import pytest

from teleop.config import SlaveConfig
from teleop.slaves import ArmFault
from teleop.slaves.ur import URArm

from .fake_rtde import FakeController, FakeRTDEControl, FakeRTDEReceive

rtde_control = pytest.importorskip("rtde_control")
rtde_receive = pytest.importorskip("rtde_receive")


def pybind_params(method) -> list[tuple[str, str | None]]:
    """(name, default) of a pybind11 method, from the first line of its docstring."""
    first = method.__doc__.strip().splitlines()[0]
    inner = first[first.index("(") + 1: first.rindex(") ->")]
    params = []
    depth, cur = 0, ""
    for ch in inner + ",":
        if ch in "[(<":
            depth += 1
        elif ch in "])>":
            depth -= 1
        if ch == "," and depth == 0:
            params.append(cur.strip())
            cur = ""
        else:
            cur += ch
    out = []
    for p in params[1:]:  # self
        name = p.split(":")[0].strip()
        default = p.split("=", 1)[1].strip() if "=" in p else None
        out.append((name, default))
    return out


@pytest.mark.parametrize("fake, real, methods", [
    (FakeRTDEControl, rtde_control.RTDEControlInterface,
     ["servoL", "servoStop", "isConnected", "stopScript", "disconnect"]),
    (FakeRTDEReceive, rtde_receive.RTDEReceiveInterface,
     ["getActualTCPPose", "isConnected", "isProtectiveStopped", "isEmergencyStopped",
      "getTimestamp", "disconnect"]),
])
def test_fake_signatures_match_the_installed_ur_rtde(fake, real, methods):
    """Every method the wrapper calls exists in the wheel with the fake's parameter names
    and defaults, so code that runs on the fake calls the real classes the same way."""
    for name in [*methods, "__init__"]:
        real_params = pybind_params(getattr(real, name))
        fake_params = list(inspect.signature(getattr(fake, name)).parameters.values())[1:]
        fake_params = [p for p in fake_params if p.name != "controller"]
        assert [p[0] for p in real_params] == [p.name for p in fake_params], name
        for (rname, rdef), fp in zip(real_params, fake_params, strict=True):
            if rdef is None:
                assert fp.default is inspect.Parameter.empty, (name, rname)
            elif re.fullmatch(r"-?[\d.]+", rdef):
                assert float(rdef) == float(fp.default), (name, rname)


def test_moveL_exists_in_the_wheel():
    assert "moveL" in dir(rtde_control.RTDEControlInterface)
    assert "speed" in rtde_control.RTDEControlInterface.moveL.__doc__


def make_arm(ctrl: FakeController, **cfg):
    c = SlaveConfig(**cfg)
    return URArm(c, connect=lambda host, f: (FakeRTDEControl(host, f, controller=ctrl),
                                             FakeRTDEReceive(host, f, controller=ctrl)),
                 retry_wait_s=0.0)


def test_ur_arm_streams_servoL_and_reads_the_actual_pose():
    """Home by moveL after servoStop, then servoL targets: the fake TCP follows, read back
    in mm; close() stops the servo, the script and disconnects."""
    ctrl = FakeController()
    arm = make_arm(ctrl)
    home = np.array([550.0, 0.0, 250.0])
    arm.start(home)
    assert ctrl.calls[:2] == ["servoStop", "moveL"]
    np.testing.assert_allclose(arm.actual_mm(), home)
    for _ in range(500):
        arm.servo(home + np.array([10.0, 0.0, 0.0]), 0.0)
    np.testing.assert_allclose(arm.actual_mm(), home + np.array([10.0, 0, 0]), atol=0.01)
    # Tool perpendicular to the surface: rotation vector of a z-down TCP is pi about x or y.
    assert np.linalg.norm(ctrl.pose[3:]) == pytest.approx(np.pi)
    arm.close()
    assert ctrl.calls[-3:] == ["servoStop", "stopScript", "disconnect"]
    arm.close()  # idempotent


def test_protective_stop_raises_a_fault_that_says_what_to_check():
    ctrl = FakeController()
    arm = make_arm(ctrl)
    arm.start(np.array([550.0, 0.0, 250.0]))
    ctrl.protective_stop = True
    with pytest.raises(ArmFault, match=r"protective stop.*teach pendant"):
        arm.servo(np.array([550.0, 0.0, 250.0]), 0.0)


def test_connection_loss_raises_a_fault_that_says_what_to_check():
    ctrl = FakeController()
    arm = make_arm(ctrl)
    arm.start(np.array([550.0, 0.0, 250.0]))
    ctrl.connected = False
    with pytest.raises(ArmFault, match=r"connection.*network cable"):
        arm.servo(np.array([550.0, 0.0, 250.0]), 0.0)


def test_connection_retries_then_a_helpful_error():
    attempts = []

    def refuse(host, f):
        attempts.append(host)
        raise RuntimeError("Connection refused")
    arm = URArm(SlaveConfig(ur_host="10.0.0.9"), connect=refuse, retry_wait_s=0.0)
    with pytest.raises(ArmFault, match=r"10\.0\.0\.9.*Remote Control"):
        arm.start(np.zeros(3))
    assert len(attempts) == 3


def test_servo_parameters_outside_ur_rtde_ranges_are_refused_up_front():
    with pytest.raises(ValueError, match="lookahead"):
        URArm(SlaveConfig(ur_lookahead_s=0.5))
    with pytest.raises(ValueError, match="gain"):
        URArm(SlaveConfig(ur_gain=50.0))
    ctrl = FakeController()
    with pytest.raises(ValueError, match="lookahead"):  # the fake enforces them too
        FakeRTDEControl("x", controller=ctrl).servoL([0.0] * 6, 0.5, 0.5, 0.002, 0.01, 300)


def test_slave_loop_holds_on_a_ur_fault():
    """A protective stop during streaming: the slave reports FAULT, stops the robot
    (servoStop, stopScript) and never commands it again."""
    from teleop import protocol as P
    from teleop.config import TeleopConfig
    from teleop.slave import SlaveLoop

    class Sock:
        sock = None

    ctrl = FakeController()
    arm = make_arm(ctrl)
    cfg = TeleopConfig()
    arm.start(np.array(cfg.mapping.origin_mm))
    loop = SlaveLoop(arm, Sock(), cfg)  # type: ignore[arg-type]
    loop.tick(0.0, 0.002)
    ctrl.protective_stop = True
    n = ctrl.calls.count("servoL")
    loop.tick(0.002, 0.002)
    assert loop.status == P.STATUS_FAULT and loop.counts["arm_faults"] == 1
    loop.tick(0.004, 0.002)
    assert ctrl.calls.count("servoL") == n + 1  # the refused one, then nothing
    assert ctrl.calls[-3:] == ["servoStop", "stopScript", "disconnect"]
    assert loop.status == P.STATUS_FAULT
