"""`teleop slave --robot ur` in a subprocess, against the fake of ur-rtde's contract (no UR
controller can run here). argv: CALLS_JSON FAULT [teleop slave arguments...].

Writes the fake controller's calls (servoL, servoStop, stopScript, ...) to CALLS_JSON when
the process ends, however the slave stopped. FAULT injects one stop path after 100 servoL:
``none``; ``pstop`` (the controller reports a protective stop); ``loop`` (reading the pose
raises: a fault inside the slave loop); ``link`` (the link socket fails: ZMQError).
"""

from __future__ import annotations

import atexit
import json
import sys

import zmq

import teleop.slave
import teleop.slaves.ur as ur
from teleop.cli import main

from .fake_rtde import FakeController, FakeRTDEControl, FakeRTDEReceive

AFTER_SERVOS = 100

if __name__ == "__main__":
    calls_path, fault, argv = sys.argv[1], sys.argv[2], sys.argv[3:]
    ctrl = FakeController()
    atexit.register(lambda: open(calls_path, "w").write(json.dumps(ctrl.calls)))

    def servos() -> int:
        return ctrl.calls.count("servoL")

    class Receive(FakeRTDEReceive):
        def isProtectiveStopped(self) -> bool:
            return ctrl.protective_stop or (fault == "pstop" and servos() >= AFTER_SERVOS)

        def getActualTCPPose(self) -> list[float]:
            if fault == "loop" and servos() >= AFTER_SERVOS:
                raise RuntimeError("injected fault while reading the pose")
            return super().getActualTCPPose()

    class Control(FakeRTDEControl):
        def servoL(self, *args) -> bool:
            if fault == "pstop" and servos() >= AFTER_SERVOS:
                ctrl.protective_stop = True
            return super().servoL(*args)

    def make_arm(cfg):
        from teleop.mapping import Mapping
        return ur.URArm(cfg.slave, tool_down=tuple(Mapping(cfg.mapping).tool_down()),
                        connect=lambda host, hz: (Control(host, hz, controller=ctrl),
                                                  Receive(host, hz, controller=ctrl)))

    teleop.slave.make_arm = make_arm
    real_wait = teleop.slave.wait_readable

    def wait_readable(sock, t_end_s, clock):
        if fault == "link" and servos() >= AFTER_SERVOS:
            raise zmq.ZMQError(zmq.ETERM, "injected link fault")
        return real_wait(sock, t_end_s, clock)

    teleop.slave.wait_readable = wait_readable
    sys.exit(main(["slave", "--robot", "ur", *argv]))
