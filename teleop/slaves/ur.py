"""Universal Robots slave through ur-rtde (servoL streaming, getActualTCPPose).

The only module that imports rtde_control / rtde_receive, and only when connecting, so
everything else (and the tests' fake) runs without a controller. Lessons from airo-mono's
UR wrapper: limits are data (SlaveConfig), servoStop before any other move, connection
retries, and errors that say what to check on the robot.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from teleop.config import SlaveConfig
from teleop.slaves import ArmFault

log = logging.getLogger(__name__)

# ur-rtde's own limits (rtde_control_interface.h): outside them servoL raises.
LOOKAHEAD_RANGE_S = (0.03, 0.2)
#: ``--ur-host sim``: a simulated UR controller (the mujoco extra) instead of a robot.
SIM_HOST = "sim"
GAIN_RANGE = (100.0, 2000.0)

CHECK_CONNECTION = ("check the network cable and address {host}, that the robot is powered "
                    "on, brakes released, and in Remote Control mode (e-Series)")
CHECK_PSTOP = ("protective stop on {host}: check the teach pendant for the cause (collision, "
               "limit), clear the area, unlock the protective stop there, then restart the slave")


def _connect_rtde(host: str, frequency_hz: float) -> tuple[Any, Any]:
    if host == SIM_HOST:  # the UR5e in MuJoCo behind the same calls (teleop/slaves/ur_sim.py)
        from teleop.slaves.ur_sim import connect_sim  # MuJoCo: the optional extra ``mujoco``

        return connect_sim(frequency_hz)
    # lazy: ur-rtde loads only for a real controller (the sim above needs none of it)
    import rtde_control
    import rtde_receive

    return (rtde_control.RTDEControlInterface(host, frequency_hz),
            rtde_receive.RTDEReceiveInterface(host, frequency_hz))


class URArm:
    """UR arm behind the Arm protocol; tool kept perpendicular to the surface."""

    name = "ur"

    def __init__(self, cfg: SlaveConfig, tool_down: tuple[float, float, float] = (0, 0, -1),
                 connect: Callable[[str, float], tuple[Any, Any]] = _connect_rtde,
                 retries: int = 3, retry_wait_s: float = 1.0) -> None:
        lo, hi = LOOKAHEAD_RANGE_S
        if not lo <= cfg.ur_lookahead_s <= hi:
            raise ValueError(f"slave.ur_lookahead_s={cfg.ur_lookahead_s} outside ur-rtde's "
                             f"[{lo}, {hi}] s")
        if not GAIN_RANGE[0] <= cfg.ur_gain <= GAIN_RANGE[1]:
            raise ValueError(f"slave.ur_gain={cfg.ur_gain} outside ur-rtde's {GAIN_RANGE}")
        self.cfg = cfg
        self.host = cfg.ur_host
        # servoL's lookahead smooths by roughly its own length: fed forward by the slave.
        self.lag_s = cfg.ur_lookahead_s + 2.0 / cfg.ur_frequency_hz
        self._connect = connect
        self._retries = retries
        self._retry_wait_s = retry_wait_s
        self._rotvec = _tool_rotvec(np.asarray(tool_down, float))
        self.ctrl: Any = None
        self.recv: Any = None

    def start(self, home_mm: np.ndarray) -> None:
        err: Exception | None = None
        for attempt in range(1, self._retries + 1):
            try:
                self.ctrl, self.recv = self._connect(self.host, self.cfg.ur_frequency_hz)
                break
            except RuntimeError as e:  # ur-rtde raises RuntimeError on connection failure
                err = e
                log.warning("UR connection attempt %d/%d to %s failed: %s", attempt,
                            self._retries, self.host, e)
                time.sleep(self._retry_wait_s)
        else:
            raise ArmFault(f"cannot connect to the UR controller: {err}; "
                           + CHECK_CONNECTION.format(host=self.host))
        self._check()
        self.ctrl.servoStop()  # never start a move on top of a running servo
        if not self.ctrl.moveL(self._pose(home_mm), 0.1, 0.5):
            raise ArmFault(f"moveL to home {home_mm} mm refused: check the home position is "
                           "reachable and inside the robot's safety planes")

    def _pose(self, p_mm: np.ndarray) -> list[float]:
        return [*(np.asarray(p_mm, float) / 1000.0).tolist(), *self._rotvec.tolist()]

    def _check(self) -> None:
        if not (self.ctrl.isConnected() and self.recv.isConnected()):
            raise ArmFault("lost the connection to the UR controller: "
                           + CHECK_CONNECTION.format(host=self.host))
        if self.recv.isProtectiveStopped():
            raise ArmFault(CHECK_PSTOP.format(host=self.host))
        if self.recv.isEmergencyStopped():
            raise ArmFault(f"emergency stop on {self.host}: release the e-stop, then restart")

    def servo(self, target_mm: np.ndarray, now_s: float) -> None:
        ok = self.ctrl.servoL(self._pose(target_mm), 0.5, 0.5, 1.0 / self.cfg.ur_frequency_hz,
                              self.cfg.ur_lookahead_s, self.cfg.ur_gain)
        if not ok:
            self._check()
            raise ArmFault(f"servoL refused by {self.host}: the control script stopped; check "
                           "the pendant's log and that no other program took control")

    def actual_mm(self) -> np.ndarray:
        return np.asarray(self.recv.getActualTCPPose()[:3], float) * 1000.0

    def hold(self) -> None:
        if self.ctrl is not None:
            self.ctrl.servoStop()

    def close(self) -> None:
        ctrl, recv = self.ctrl, self.recv
        self.ctrl = self.recv = None
        if ctrl is not None:
            try:
                ctrl.servoStop()
                ctrl.stopScript()
            finally:
                ctrl.disconnect()
        if recv is not None:
            recv.disconnect()

    def __enter__(self) -> URArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _tool_rotvec(tool_down: np.ndarray) -> np.ndarray:
    """Rotation vector of a TCP whose z axis points along ``tool_down``."""
    z = tool_down / np.linalg.norm(tool_down)
    x = np.array([1.0, 0.0, 0.0]) - z * z[0]
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - z * z[1]
    x /= np.linalg.norm(x)
    return Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z])).as_rotvec()
