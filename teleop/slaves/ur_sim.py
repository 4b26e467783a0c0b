"""A simulated UR controller: the ur-rtde calls the UR slave makes, answered by a UR5e in
MuJoCo (the Menagerie model, teleop/models/). ``teleop slave --robot ur --ur-host sim``.

What it copies of the real controller (ur-rtde's RTDEControlInterface and
RTDEReceiveInterface, URScript's servoj/servol):
- a 500 Hz control loop running on its own clock (here: stepped up to the caller's
  wall-clock time at every call, 1 kHz physics, two steps per control period; a caller
  starved for up to MAX_CATCHUP_S finds the arm where the real one, which never waits
  for its client, would be);
- ``servoL(pose, speed, acceleration, time, lookahead_time, gain)``: the pose is solved to
  joint targets; the controller moves its joint reference towards them as a first-order
  lag of time constant ``lookahead_time`` ("smoothens the trajectory with this lookahead
  time"), at most the joints' speed limit (UR5e: 180 deg/s every joint), and the joint
  servos follow the reference with a proportional gain scaled by ``gain`` ("proportional
  gain for following target position": 300, ur-rtde's default, is the Menagerie's
  actuator stiffness). Out-of-range lookahead (0.03-0.2 s) or gain (100-2000) raise as
  ur-rtde does;
- gravity compensation (the controller's own), the Menagerie's joint limits, torque
  limits (150 N m shoulder/elbow, 28 N m wrists), armature and damping;
- protective stop when a joint reference would leave its range or a joint lags its
  reference by more than FOLLOWING_ERROR_RAD (a collision or an impossible move): the arm
  holds where it is and every command returns False until ``unlockProtectiveStop``;
- ``servoStop`` (decelerate and hold), ``stopScript`` (the control script ends: commands
  return False), ``moveL`` (blocking straight line), ``getActualTCPPose`` (the flange,
  base frame, axis-angle), ``getActualQ``, ``isProtectiveStopped``, ``getSafetyMode``.

What it is not: UR's firmware. The servo law is the documented behaviour put as
equations (docs/teleop.md, "UR5e in MuJoCo"); the real controller's trajectory filter is
not published.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

log = logging.getLogger(__name__)

MODEL_PATH = (Path(__file__).resolve().parent.parent / "models" / "mujoco_menagerie"
              / "universal_robots_ur5e" / "ur5e.xml")
CONTROL_HZ = 500.0
PHYSICS_DT_S = 0.001
JOINT_SPEED_RAD_S = math.pi  # UR5e data sheet: 180 deg/s on every joint
GAIN_AT_MODEL_KP = 300.0  # ur-rtde's default servoL gain maps to the Menagerie's kp
JOINT_ACCEL_RAD_S2 = 40.0  # the reference's acceleration bound (not published by UR: chosen)
FOLLOWING_ERROR_RAD = 0.3  # a joint this far behind its reference: protective stop
MAX_CATCHUP_S = 0.5  # the controller runs on while its caller is starved, up to this
LOOKAHEAD_RANGE_S = (0.03, 0.2)
GAIN_RANGE = (100.0, 2000.0)
SAFETY_NORMAL, SAFETY_PROTECTIVE_STOP = 1, 3
#: Where the arm stands at power-on: (0.55, 0, 0.25) m, tool down, flange x along base x
#: (the default mapping's home; teleop.config.MappingConfig.origin_mm).
READY_POSE = (0.55, 0.0, 0.25, -math.pi, 0.0, 0.0)  # ur-rtde getSafetyMode values


class SimURController:
    """The UR5e and its controller state; one instance behind both interfaces."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        import mujoco  # the optional extra ``mujoco``; connect_sim checks it first

        self._mj = mujoco
        self.model = mujoco.MjModel.from_xml_path(str(MODEL_PATH))
        self.model.opt.timestep = PHYSICS_DT_S
        self.model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        self.data = mujoco.MjData(self.model)
        self._kin = mujoco.MjData(self.model)  # for inverse kinematics, never stepped
        mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        self._site = self.model.site("tcp").id
        self._jac = np.zeros((6, self.model.nv))
        self._err = np.zeros(6)
        self._damping = 1e-6 * np.eye(6)
        # Powered on at rest in the ready pose: the tool down over the default workspace
        # centre, reached from the Menagerie's home posture (elbow up).
        self.data.qpos[:] = self.ik(READY_POSE, self.data.qpos, iters=100)
        mujoco.mj_forward(self.model, self.data)
        self._kp_model = self.model.actuator_gainprm[:, 0].copy()
        self.q_lo = self.model.jnt_range[:, 0].copy()
        self.q_hi = self.model.jnt_range[:, 1].copy()
        self.q_ref = self.data.qpos.copy()
        self.q_target: np.ndarray | None = None
        self._v_ref = np.zeros(self.model.nv)  # the reference's joint speeds
        self.lookahead_s = 0.1
        self.gain = GAIN_AT_MODEL_KP
        self.connected = True
        self.script_running = True
        self.protective_stop = False
        self.stop_reason = ""
        self.clock = clock
        self.t_sim_s = 0.0
        self._offset_s = clock()  # wall - sim
        self._step_count = 0
        self.resyncs = 0

    # -- time ---------------------------------------------------------------------------
    def sync(self) -> None:
        """Run the controller and physics up to the caller's clock."""
        due = self.clock() - self._offset_s
        if due - self.t_sim_s > MAX_CATCHUP_S:
            self.resyncs += 1
            self._offset_s += due - self.t_sim_s - MAX_CATCHUP_S
            due = self.t_sim_s + MAX_CATCHUP_S
        while self.t_sim_s + PHYSICS_DT_S <= due + 1e-9:
            self.step()

    def step(self) -> None:
        """One physics step; the control loop runs on every second one (500 Hz)."""
        if self._step_count % round(1.0 / (CONTROL_HZ * PHYSICS_DT_S)) == 0:
            self._control(1.0 / CONTROL_HZ)
        # The controller's dynamic model: gravity and Coriolis torques fed forward (the bias
        # of the last step), so the servos' stiffness only has to follow, not to hold.
        self.data.qfrc_applied[:] = self.data.qfrc_bias
        self._mj.mj_step(self.model, self.data)
        self._step_count += 1
        self.t_sim_s += PHYSICS_DT_S

    def _control(self, dt_s: float) -> None:
        if self.protective_stop:
            return
        q = self.data.qpos
        dv = JOINT_ACCEL_RAD_S2 * dt_s
        if self.q_target is not None and self.script_running:
            v = (self.q_target - self.q_ref) / self.lookahead_s
            v = np.clip(v, -JOINT_SPEED_RAD_S, JOINT_SPEED_RAD_S)
        else:  # servoStop, stopScript: decelerate to rest where the reference is
            v = np.zeros_like(self._v_ref)
        v = np.clip(v, self._v_ref - dv, self._v_ref + dv)
        self._v_ref = v
        nxt = self.q_ref + v * dt_s
        if not ((nxt >= self.q_lo).all() and (nxt <= self.q_hi).all()):
            self._pstop("joint limit")
            return
        self.q_ref = nxt
        err = np.abs(q - self.q_ref)
        if float(err.max()) > FOLLOWING_ERROR_RAD:
            self._pstop(f"joint {int(err.argmax())} lags its reference by "
                        f"{math.degrees(float(err.max())):.0f} deg")
            return
        self.data.ctrl[:] = self.q_ref

    def _set_gain(self, gain: float) -> None:
        kp = self._kp_model * gain / GAIN_AT_MODEL_KP
        self.model.actuator_gainprm[:, 0] = kp
        self.model.actuator_biasprm[:, 1] = -kp
        self.gain = gain

    def _pstop(self, why: str) -> None:
        log.warning("simulated UR: protective stop (%s)", why)
        self.protective_stop = True
        self.stop_reason = why
        self.q_target = None
        self.q_ref = self.data.qpos.copy()  # brakes: hold where the arm is
        self._v_ref[:] = 0.0
        self.data.ctrl[:] = self.q_ref

    # -- kinematics -----------------------------------------------------------------------
    def tcp_pose(self, qpos: np.ndarray | None = None) -> list[float]:
        d = self.data if qpos is None else self._kin
        if qpos is not None:
            d.qpos[:] = qpos
        self._mj.mj_kinematics(self.model, d)
        quat = np.empty(4)  # w, x, y, z
        self._mj.mju_mat2Quat(quat, d.site_xmat[self._site])
        if quat[0] < 0:
            quat = -quat
        s = float(np.linalg.norm(quat[1:]))
        rv = quat[1:] * (2.0 * math.atan2(s, quat[0]) / s) if s > 1e-12 else np.zeros(3)
        return [*d.site_xpos[self._site].tolist(), *rv.tolist()]

    def ik(self, pose: list[float], seed: np.ndarray, iters: int = 8) -> np.ndarray:
        return self.ik_matrix(np.asarray(pose[:3], float),
                              _rotvec_matrix(np.asarray(pose[3:6], float)), seed, iters)

    def ik_matrix(self, p_goal: np.ndarray, r_goal: np.ndarray, seed: np.ndarray,
                  iters: int = 8) -> np.ndarray:
        """Joint positions putting the flange at ``p_goal``, ``r_goal`` by damped least
        squares, dq = J^T (J J^T + 1e-6 I)^-1 e (6-D error: position, and the rotation
        error 0.5 vee(R_goal R^T - R R_goal^T)). Streaming calls take one step from the
        previous solution (each tick corrects the whole remaining error)."""
        mj = self._mj
        d = self._kin
        q = np.array(seed, float)
        jac = self._jac
        err = self._err
        for k in range(iters):
            d.qpos[:] = q
            mj.mj_kinematics(self.model, d)
            mj.mj_comPos(self.model, d)
            err[:3] = p_goal - d.site_xpos[self._site]
            s = r_goal @ d.site_xmat[self._site].reshape(3, 3).T
            err[3] = 0.5 * (s[2, 1] - s[1, 2])
            err[4] = 0.5 * (s[0, 2] - s[2, 0])
            err[5] = 0.5 * (s[1, 0] - s[0, 1])
            if k and float(err @ err) < 1e-14:
                break
            mj.mj_jacSite(self.model, d, jac[:3], jac[3:], self._site)
            q += jac.T @ np.linalg.solve(jac @ jac.T + self._damping, err)
        return q

    # -- commands -------------------------------------------------------------------------
    def ok(self) -> bool:
        return self.connected and self.script_running and not self.protective_stop

    def servo_l(self, pose: list[float], lookahead_s: float, gain: float) -> bool:
        self.sync()
        if not self.ok():
            return False
        seed = self.q_target if self.q_target is not None else self.q_ref
        self.q_target = self.ik(pose, seed, iters=1)
        self.lookahead_s = lookahead_s
        if gain != self.gain:
            self._set_gain(gain)
        return True

    def servo_stop(self) -> bool:
        """Decelerate to rest and hold (the reference stops where it is now)."""
        self.sync()
        self.q_target = None
        return self.ok()

    def move_l(self, pose: list[float], speed_m_s: float) -> bool:
        """Blocking straight line at ``speed_m_s`` (the orientation slerped along it)."""
        self.sync()
        if not self.ok():
            return False
        start = self.tcp_pose(self.q_ref)
        r_start = _rotvec_matrix(np.asarray(start[3:], float))
        r_goal = _rotvec_matrix(np.asarray(pose[3:], float))
        turn = Rotation.from_matrix(r_start.T @ r_goal).as_rotvec()  # in the start frame
        dist = float(np.linalg.norm(np.subtract(pose[:3], start[:3])))
        n = max(1, math.ceil(max(dist / speed_m_s, float(np.linalg.norm(turn))) * CONTROL_HZ))
        self.q_target = None
        q = self.q_ref
        for k in range(1, n + 1):
            s = k / n
            p = (1 - s) * np.asarray(start[:3]) + s * np.asarray(pose[:3])
            q = self.ik_matrix(p, r_start @ _rotvec_matrix(s * turn), q)
            if np.any(q < self.q_lo) or np.any(q > self.q_hi):
                self._pstop("moveL through a joint limit")
                return False
            self.q_ref = q
            self._v_ref[:] = 0.0
            for _ in range(round(1.0 / (CONTROL_HZ * PHYSICS_DT_S))):
                self.step()
            if self.protective_stop:
                return False
        for _ in range(300):  # settle (0.3 s)
            self.step()
        self._offset_s = self.clock() - self.t_sim_s  # the move took its time; now live
        return self.ok()


def _rotvec_matrix(rv: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation matrix of an axis-angle vector."""
    ang = float(np.linalg.norm(rv))
    if ang < 1e-12:
        return np.eye(3)
    k = rv / ang
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(ang) * kx + (1.0 - math.cos(ang)) * (kx @ kx)


class SimRTDEControl:
    """ur-rtde's RTDEControlInterface, the methods the UR slave calls (and a few more)."""

    def __init__(self, controller: SimURController) -> None:
        self.c = controller

    def servoL(self, pose, speed, acceleration, time, lookahead_time, gain) -> bool:
        if len(pose) != 6:
            raise ValueError("pose must have 6 elements")
        if not LOOKAHEAD_RANGE_S[0] <= lookahead_time <= LOOKAHEAD_RANGE_S[1]:
            raise ValueError(f"lookahead_time {lookahead_time} is not within [0.03, 0.2]")
        if not GAIN_RANGE[0] <= gain <= GAIN_RANGE[1]:
            raise ValueError(f"gain {gain} is not within [100, 2000]")
        return self.c.servo_l(list(pose), float(lookahead_time), float(gain))

    def servoStop(self, a: float = 10.0) -> bool:
        return self.c.servo_stop()

    def moveL(self, pose, speed=0.25, acceleration=1.2, asynchronous=False) -> bool:
        return self.c.move_l(list(pose), float(speed))

    def stopScript(self) -> None:
        self.c.script_running = False
        self.c.q_target = None

    def triggerProtectiveStop(self) -> bool:
        self.c.sync()
        self.c._pstop("triggered by the client")
        return True

    def isConnected(self) -> bool:
        return self.c.connected

    def disconnect(self) -> None:
        self.c.connected = False


class SimRTDEReceive:
    """ur-rtde's RTDEReceiveInterface, the reads the UR slave makes (and a few more)."""

    def __init__(self, controller: SimURController) -> None:
        self.c = controller

    def getActualTCPPose(self) -> list[float]:
        self.c.sync()
        return self.c.tcp_pose()

    def getActualQ(self) -> list[float]:
        self.c.sync()
        return self.c.data.qpos.tolist()

    def isProtectiveStopped(self) -> bool:
        self.c.sync()
        return self.c.protective_stop

    def isEmergencyStopped(self) -> bool:
        return False

    def getSafetyMode(self) -> int:
        return SAFETY_PROTECTIVE_STOP if self.c.protective_stop else SAFETY_NORMAL

    def isConnected(self) -> bool:
        return self.c.connected

    def disconnect(self) -> None:
        pass


def unlock_protective_stop(controller: SimURController) -> None:
    """The pendant's "unlock": the arm may move again from where it stands."""
    controller.protective_stop = False
    controller.stop_reason = ""
    controller.q_ref = controller.data.qpos.copy()


def connect_sim(frequency_hz: float = CONTROL_HZ, clock: Callable[[], float] = time.monotonic
                ) -> tuple[SimRTDEControl, SimRTDEReceive]:
    """Both interfaces on one new simulated controller (``--ur-host sim``)."""
    try:
        import mujoco  # noqa: F401
    except ImportError:
        # ValueError, not RuntimeError: no point retrying, nothing on the network to check.
        raise ValueError("--ur-host sim needs MuJoCo: pip install 'fydpad[mujoco]'") from None
    if abs(frequency_hz - CONTROL_HZ) > 1e-6:
        raise RuntimeError(f"the simulated UR5e runs at {CONTROL_HZ:.0f} Hz (e-Series), "
                           f"asked for {frequency_hz:g} Hz")
    c = SimURController(clock)
    return SimRTDEControl(c), SimRTDEReceive(c)
