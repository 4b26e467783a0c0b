"""Simulated slave: the KUKA LBR iiwa 7-DoF arm of pybullet_data, headless, 1 kHz physics.

Inverse kinematics plus joint position control with the joints' speed limits: it moves
like an arm (finite speed, joint limits), not a teleporting point. The paper's slave
was a KUKA lightweight arm (IV-B).
"""

from __future__ import annotations

import logging
import math

import numpy as np

log = logging.getLogger(__name__)

PHYSICS_DT_S = 0.001
EE_LINK = 6  # lbr_iiwa_link_7, the flange
MAX_CATCHUP_STEPS = 60  # beyond this the process was starved; re-sync instead of spiralling


class SimArm:
    """PyBullet iiwa behind the Arm protocol. Time is the slave loop's clock."""

    name = "sim"

    def __init__(self, joint_speed_rad_s: float = 1.7, lag_s: float = 0.002,
                 tool_down: tuple[float, float, float] = (0.0, 0.0, -1.0)) -> None:
        self.joint_speed_rad_s = joint_speed_rad_s
        self.lag_s = lag_s
        self._tool_down = np.asarray(tool_down, float)
        self._p = None
        self._cid = -1
        self._robot = -1
        self._t_sim_s: float | None = None
        self.resyncs = 0

    def start(self, home_mm: np.ndarray) -> None:
        # lazy: pybullet loads when the arm starts, not with every import of teleop.slave
        import pybullet as p
        import pybullet_data

        self._p = p
        self._cid = p.connect(p.DIRECT)
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=self._cid)
        self._robot = p.loadURDF("kuka_iiwa/model.urdf", useFixedBase=True,
                                 physicsClientId=self._cid)
        p.setTimeStep(PHYSICS_DT_S, physicsClientId=self._cid)
        p.setGravity(0, 0, -9.81, physicsClientId=self._cid)
        info = [p.getJointInfo(self._robot, j, physicsClientId=self._cid) for j in range(7)]
        self._lo = [i[8] for i in info]
        self._hi = [i[9] for i in info]
        self._rest = [0.0, 0.6, 0.0, -1.4, 0.0, 1.1, 0.0]  # elbow up, wrist over the table
        self._orn = self._orientation()
        for j, q in enumerate(self._rest):
            p.resetJointState(self._robot, j, q, physicsClientId=self._cid)
        # Settle onto home by IK iterations on the kinematics (start-up, before streaming).
        for k in range(20):
            q = self._ik(np.asarray(home_mm, float), nullspace=k < 10)
            for j in range(7):
                p.resetJointState(self._robot, j, q[j], physicsClientId=self._cid)
        self._command(self._ik(np.asarray(home_mm, float)))
        err = float(np.linalg.norm(self.actual_mm() - home_mm))
        if err > 2.0:
            raise RuntimeError(f"sim arm cannot reach home {home_mm} mm (off by {err:.1f} mm): "
                               "check mapping.origin_mm is within the iiwa's reach")

    def _orientation(self) -> list[float]:
        # Flange z axis along tool_down; x axis as close to base x as possible.
        z = self._tool_down / np.linalg.norm(self._tool_down)
        x = np.array([1.0, 0.0, 0.0]) - z * z[0]
        if np.linalg.norm(x) < 1e-6:
            x = np.array([0.0, 1.0, 0.0]) - z * z[1]
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        m = np.column_stack([x, y, z])
        # Rotation matrix -> quaternion (x, y, z, w).
        w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
        qx = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2,
                           m[2, 1] - m[1, 2])
        qy = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2,
                           m[0, 2] - m[2, 0])
        qz = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2,
                           m[1, 0] - m[0, 1])
        return [qx, qy, qz, w]

    def _ik(self, target_mm: np.ndarray, nullspace: bool = False) -> list[float]:
        """Joint targets for a tool position; seeded by the current joint state.

        The null-space variant (rest posture, joint limits) picks the start posture; it
        stops ~2 mm short, so streaming uses the plain solver, exact to 0.01 mm.
        """
        p = self._p
        kw = {}
        if nullspace:
            rng = [h - lo for lo, h in zip(self._lo, self._hi, strict=True)]
            kw = dict(lowerLimits=self._lo, upperLimits=self._hi, jointRanges=rng,
                      restPoses=self._rest)
        q = p.calculateInverseKinematics(
            self._robot, EE_LINK, (target_mm / 1000.0).tolist(), self._orn,
            maxNumIterations=100 if nullspace else 12, residualThreshold=1e-6,
            physicsClientId=self._cid, **kw)
        return [min(max(v, lo), hi) for v, lo, hi in zip(q, self._lo, self._hi, strict=True)]

    def _command(self, q: list[float]) -> None:
        p = self._p
        for j in range(7):
            p.setJointMotorControl2(self._robot, j, p.POSITION_CONTROL, targetPosition=q[j],
                                    force=300.0, maxVelocity=self.joint_speed_rad_s,
                                    positionGain=0.3, velocityGain=1.0,
                                    physicsClientId=self._cid)

    def servo(self, target_mm: np.ndarray, now_s: float) -> None:
        if self._p is None:
            raise RuntimeError("SimArm.servo before start()")
        self._command(self._ik(np.asarray(target_mm, float)))
        if self._t_sim_s is None:
            self._t_sim_s = now_s
        steps = int((now_s - self._t_sim_s) / PHYSICS_DT_S)
        if steps > MAX_CATCHUP_STEPS:
            self.resyncs += 1
            log.warning("sim slave starved for %.0f ms: physics re-synced", 1e3 * steps * 1e-3)
            self._t_sim_s = now_s - MAX_CATCHUP_STEPS * PHYSICS_DT_S
            steps = MAX_CATCHUP_STEPS
        for _ in range(max(steps, 0)):
            self._p.stepSimulation(physicsClientId=self._cid)
        self._t_sim_s += max(steps, 0) * PHYSICS_DT_S

    def actual_mm(self) -> np.ndarray:
        st = self._p.getLinkState(self._robot, EE_LINK, computeForwardKinematics=True,
                                  physicsClientId=self._cid)
        return np.asarray(st[4]) * 1000.0

    def hold(self) -> None:
        q = [self._p.getJointState(self._robot, j, physicsClientId=self._cid)[0]
             for j in range(7)]
        self._command(q)

    def close(self) -> None:
        if self._p is not None and self._cid >= 0:
            self._p.disconnect(physicsClientId=self._cid)
        self._p = None
        self._cid = -1

    def __enter__(self) -> SimArm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
