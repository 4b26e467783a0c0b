"""A fake ur-rtde copying its contract (test_ur.py checks the signatures against the wheel).

Contract copied: servoL's argument ranges raise (pybind11 maps ur-rtde's std::range_error
to ValueError); commands return False when the arm is protective-stopped or the script
is stopped; the controller holds the last servo target; a virtual clock advances one
control period per servoL, and the TCP follows the target with the lookahead as lag.
"""

from __future__ import annotations

import numpy as np


class FakeController:
    def __init__(self, frequency_hz: float = 500.0) -> None:
        self.dt_s = 1.0 / frequency_hz
        self.t_s = 0.0
        self.pose = [0.5, 0.0, 0.3, 0.0, 3.14159, 0.0]
        self.target: list[float] | None = None
        self.lookahead_s = 0.1
        self.protective_stop = False
        self.connected = True
        self.script_running = True
        self.calls: list[str] = []

    def advance(self) -> None:
        self.t_s += self.dt_s
        if self.target is not None and self.script_running and not self.protective_stop:
            k = min(1.0, self.dt_s / self.lookahead_s)
            p = np.asarray(self.pose[:3]) + k * (np.asarray(self.target[:3]) - self.pose[:3])
            self.pose = [*p.tolist(), *self.target[3:]]


class FakeRTDEControl:
    def __init__(self, hostname: str, frequency: float = -1.0, flags: int = 1,
                 ur_cap_port: int = 50002, rt_priority: int = 0,
                 controller: FakeController | None = None) -> None:
        self.c = controller or FakeController()

    def _ok(self) -> bool:
        return self.c.connected and self.c.script_running and not self.c.protective_stop

    def servoL(self, arg0, arg1, arg2, arg3, arg4, arg5) -> bool:
        if len(arg0) != 6:
            raise ValueError("pose must have 6 elements")
        if not 0.03 <= arg4 <= 0.2:
            raise ValueError(f"lookahead_time {arg4} is not within [0.03, 0.2]")
        if not 100 <= arg5 <= 2000:
            raise ValueError(f"gain {arg5} is not within [100, 2000]")
        self.c.calls.append("servoL")
        if not self._ok():
            return False
        self.c.target = list(arg0)
        self.c.lookahead_s = arg4
        self.c.advance()
        return True

    def servoStop(self, a: float = 10.0) -> bool:
        self.c.calls.append("servoStop")
        self.c.target = None  # stop where the arm is
        return self._ok()

    def moveL(self, pose, speed=0.25, acceleration=1.2, asynchronous=False) -> bool:
        self.c.calls.append("moveL")
        if not self._ok():
            return False
        self.c.pose = list(pose)
        return True

    def isConnected(self) -> bool:
        return self.c.connected

    def stopScript(self) -> None:
        self.c.calls.append("stopScript")
        self.c.script_running = False

    def disconnect(self) -> None:
        self.c.calls.append("disconnect")
        self.c.connected = False


class FakeRTDEReceive:
    def __init__(self, hostname: str, frequency: float = -1.0, variables: list[str] | None = None,
                 verbose: bool = False, use_upper_range_registers: bool = False,
                 rt_priority: int = 0, controller: FakeController | None = None) -> None:
        self.c = controller or FakeController()

    def getActualTCPPose(self) -> list[float]:
        return list(self.c.pose)

    def isConnected(self) -> bool:
        return self.c.connected

    def isProtectiveStopped(self) -> bool:
        return self.c.protective_stop

    def isEmergencyStopped(self) -> bool:
        return False

    def getTimestamp(self) -> float:
        return self.c.t_s

    def disconnect(self) -> None:
        self.c.connected = False
