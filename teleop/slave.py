"""The slave loop: read samples, keep the newest valid one, predict, limit, servo, report.

Runs at ``slave.period_s`` (2 ms); the sim arm steps its 1 kHz physics inside. Each tick
drains every readable message (latest-only: a stale sample never waits behind a fresh
one), so the link latency is the socket's, not the tick's.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable

import numpy as np
import zmq

from teleop import protocol as P
from teleop.admission import Admission, peer_name
from teleop.config import TeleopConfig
from teleop.link import LoggingAuthenticator, SlaveSocket, wait_readable
from teleop.mapping import Mapping
from teleop.predict import IMMPredictor, Predictor
from teleop.safety import MotionLimiter, Watchdog
from teleop.slaves import Arm, ArmFault
from teleop.slaves.sim import SimArm

log = logging.getLogger(__name__)


class SlaveLoop:
    """One slave: an arm, a bound socket, the safety chain. Not thread-safe; one thread runs it."""

    def __init__(self, arm: Arm, sock: SlaveSocket, cfg: TeleopConfig | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.cfg = cfg or TeleopConfig()
        self.arm = arm
        self.sock = sock
        self.clock = clock
        self.mapping = Mapping(self.cfg.mapping)
        self.admission = Admission(self.cfg.safety)
        self.watchdog = Watchdog(self.cfg.safety.watchdog_s)
        pc = self.cfg.prediction
        # x, y restart at every touch (unknown while lifted). z restarts too, seeded with
        # the last lifted sample (indentation 0): the touch-down is then a ramp from 0.
        self.predictor = Predictor(pc.window, pc.degree, pc.max_horizon_s)
        self.predictor_z: Predictor | IMMPredictor
        if pc.method_z == "imm":
            self.predictor_z = IMMPredictor(pc.noise_z_mm, tuple(pc.jerk_psd_z), pc.mode_stay,
                                            pc.max_horizon_s, pc.mode_start)
        elif pc.method_z == "poly":
            self.predictor_z = Predictor(pc.window_z, pc.degree, pc.max_horizon_s)
        else:
            raise ValueError(f"prediction.method_z must be 'imm' or 'poly', got {pc.method_z!r}")
        self.lag_s = pc.arm_lag_s if pc.arm_lag_s > 0 else arm.lag_s
        self.home_mm = self.mapping.to_robot(np.zeros(3))
        self.limiter = MotionLimiter(self.cfg.safety, self.home_mm)
        self.status = P.STATUS_IDLE
        self.counts: Counter[str] = Counter()
        self.peer: bytes | None = None  # the owner, or the last one: periodic states go there
        self._latest: P.Sample | None = None
        self._latest_recv_s = math.nan
        self._contact = False
        self._gliding = False
        self._glide_speed_mm_s = self.cfg.safety.resume_speed_mm_s
        self._touchdown = False
        self._was_alive = False
        self._actual_mm = self.home_mm.copy()
        self._hold_since_s = math.nan  # slave clock when the operator hold began
        self.stopped = False  # the robot was stopped (fault, long hold): never servo again
        self.t_start_s = math.nan
        self.t_end_s = math.nan

    # -- receiving ----------------------------------------------------------------------
    def _on_message(self, frames: list[bytes], now_s: float) -> None:
        self.counts["messages"] += 1
        if len(frames) != 2:
            self.counts["malformed"] += 1
            return
        ident, buf = frames
        try:
            s = P.decode_sample(buf)
        except P.ProtocolError as e:
            self.counts["malformed"] += 1
            log.debug("malformed message: %s", e)
            return
        self.counts["received"] += 1
        reason = self.admission.judge(ident, s, now_s)
        if reason is None:
            if self.admission.acquired:
                self._new_owner(ident)
            self.watchdog.feed(now_s)
            self._accept(s, now_s)
            self._latest_recv_s = now_s
            self._send_state(P.REASON_ACK, now_s, s)
        else:
            self._send_state(P.REASON_REFUSED, now_s, s, to=ident,
                             status=P.STATUS_NOT_OWNER if reason == "not_owner" else None)

    @property
    def offset_s(self) -> float | None:
        """Slave clock - the owner's clock (+ a short latency), teleop/admission.py."""
        return self.admission.owner_offset_s()

    def _new_owner(self, ident: bytes) -> None:
        """A master took the free arm (only from a hold): start its history afresh; the
        command glides to its finger at resume speed (``_target_ws``), never jumps."""
        if self.peer is not None and self.peer != ident:
            log.info("master %s takes over from %s", peer_name(ident), peer_name(self.peer))
        self.peer = ident
        self.predictor.reset()
        self.predictor_z.reset()
        self._latest = None
        self._contact = False
        self._hold_since_s = math.nan

    def _accept(self, s: P.Sample, now_s: float) -> None:
        self.counts["accepted"] += 1
        if s.operator_hold:
            # Stand still; never extrapolate across the hold, glide back on release.
            if math.isnan(self._hold_since_s):
                self._hold_since_s = now_s
                self.counts["operator_holds"] += 1
                log.info("operator hold: standing still")
            self.predictor.reset()
            self.predictor_z.reset()
            self._contact = False
            self._latest = s
            return
        if not math.isnan(self._hold_since_s):
            log.info("operator hold released after %.1f s: gliding back at %.0f mm/s",
                     now_s - self._hold_since_s, self.cfg.safety.resume_speed_mm_s)
            self._hold_since_s = math.nan
            self._gliding = True
            self._glide_speed_mm_s = self.cfg.safety.resume_speed_mm_s
        # Predictors run on the owner's capture clock (strictly increasing: admission);
        # "now" is mapped into it with the owner's clock offset.
        t_slave = s.t_capture_s
        if s.contact != self._contact or (self._latest is not None
                                          and s.hold_mode != self._latest.hold_mode):
            # Never extrapolate across a touch-down or lift-off (z keeps its seed: below).
            self.predictor.reset()
            if s.contact == self._contact:
                self.predictor_z.reset()
        if s.contact and not self._contact:
            self._touchdown = True
        if s.contact:
            self.predictor.add(t_slave, np.array([s.x_mm, s.y_mm]))
            self.predictor_z.add(t_slave, np.array([s.z_mm]))
        else:
            self.predictor_z.reset()
            self.predictor_z.add(t_slave, np.array([0.0]))  # seed for the next touch-down
        self._contact = s.contact
        self._latest = s

    def _send_state(self, reason: int, now_s: float, echo: P.Sample | None,
                    to: bytes | None = None, status: int | None = None) -> None:
        to = to or self.peer
        if to is None:
            return
        cmd_ws = self.mapping.to_workspace(self.limiter.cmd_mm)
        act_ws = self.mapping.to_workspace(self._actual_mm)
        e = echo or self._latest
        st = P.State(status=self.status if status is None else status, reason=reason,
                     echo_seq=e.seq if e else 0,
                     t_echo_send_s=e.t_send_s if e else math.nan,
                     t_echo_recv_s=now_s if echo is not None else self._latest_recv_s,
                     t_slave_s=self.clock() if reason != P.REASON_TICK else now_s,
                     cmd_mm=tuple(cmd_ws), actual_mm=tuple(act_ws),
                     received=self.counts["received"], dropped=self.admission.dropped_total)
        try:
            self.sock.sock.send_multipart([to, P.encode_state(st)], zmq.NOBLOCK)
        except zmq.ZMQError:
            self.counts["state_send_failed"] += 1

    # -- control ------------------------------------------------------------------------
    def _target_ws(self, now_s: float) -> np.ndarray | None:
        """Workspace target for this tick, or None to hold."""
        alive = self.watchdog.alive(now_s)
        if not alive:
            if self._was_alive:
                log.warning("no valid sample for %.0f ms: holding", 1e3 * self.watchdog.timeout_s)
                self.predictor.reset()
                self.predictor_z.reset()
            self._was_alive = False
            if self.admission.owner is not None:
                self.admission.release()
                self._hold_since_s = math.nan
            if self._latest is not None:
                self.status = P.STATUS_WATCHDOG_HOLD
            return None
        if not self._was_alive:
            self._gliding = True  # resume: glide to the finger, no jump
            self._glide_speed_mm_s = self.cfg.safety.resume_speed_mm_s
        self._was_alive = True
        s = self._latest
        cmd_ws = self.mapping.to_workspace(self.limiter.cmd_mm)
        if s.operator_hold:
            self.status = P.STATUS_OPERATOR_HOLD
            stop_s = self.cfg.safety.operator_hold_stop_s
            if stop_s > 0 and now_s - self._hold_since_s > stop_s:
                self._stop_robot(P.STATUS_STOPPED,
                                 f"operator hold longer than {stop_s:g} s "
                                 "(safety.operator_hold_stop_s)")
            return None
        if not s.contact:
            self.status = P.STATUS_CLUTCH
            return np.array([cmd_ws[0], cmd_ws[1], 0.0])  # hold x, y; back to the surface
        self.status = P.STATUS_TRACKING
        if s.hold_mode or not self.cfg.prediction.enabled:
            tgt = np.array([s.x_mm, s.y_mm, s.z_mm])
        else:
            t_ahead = now_s - (self.offset_s or 0.0) + self.lag_s
            tgt = np.concatenate([self.predictor.predict_flat(t_ahead),
                                  self.predictor_z.predict_flat(t_ahead)])
        tgt[2] = max(tgt[2], 0.0)  # in contact the finger is never above the fabric
        if self._touchdown:
            # After a clutch the finger may touch elsewhere: glide there instead of jumping.
            self._touchdown = False
            if (not self._gliding and float(np.linalg.norm(tgt[:2] - cmd_ws[:2]))
                    > self.cfg.safety.reengage_jump_mm):
                self._gliding = True
                self._glide_speed_mm_s = self.cfg.safety.reengage_speed_mm_s
        if self._gliding:
            # In transit the arm is behind the finger anyway: never press deeper than the
            # finger was measured (the touch-down ramp's extrapolation would dive first).
            tgt[2] = min(tgt[2], max(s.z_mm, 0.0))
        return tgt

    def _stop_robot(self, status: int, why: str) -> None:
        """Stop the robot for good (UR: servoStop, stopScript, disconnect): this slave
        process never moves it again; it keeps answering with ``status``."""
        self.status = status
        if self.stopped:
            return
        self.stopped = True
        log.error("robot stopped: %s; restart the slave to continue", why)
        try:
            self.arm.close()
        except Exception:  # the arm is already gone; nothing more to do safely
            log.exception("stopping the robot failed")

    def tick(self, now_s: float, dt_s: float) -> None:
        tgt_ws = self._target_ws(now_s)
        if tgt_ws is not None and not np.all(np.isfinite(tgt_ws)):
            # Finite samples far out of range can overflow the prediction: hold instead.
            self.counts["nonfinite_targets"] += 1
            tgt_ws = None
        if tgt_ws is None:
            cmd = self.limiter.hold(dt_s)
        else:
            tgt = self.mapping.to_robot(tgt_ws)
            if self._gliding:
                if np.linalg.norm(tgt - self.limiter.cmd_mm) <= self.cfg.safety.resume_done_mm:
                    self._gliding = False
            self.limiter.speed_cap_mm_s = (min(self._glide_speed_mm_s,
                                               self.cfg.safety.max_speed_mm_s)
                                           if self._gliding else self.cfg.safety.max_speed_mm_s)
            cmd = self.limiter.step(tgt, dt_s)
        if self.stopped:
            self.status = P.STATUS_FAULT if self.counts["arm_faults"] else P.STATUS_STOPPED
        else:
            try:
                self.arm.servo(cmd, now_s)
                self._actual_mm = self.arm.actual_mm()
            except ArmFault as e:
                self.counts["arm_faults"] += 1
                self._stop_robot(P.STATUS_FAULT, f"robot fault: {e}")
        self._send_state(P.REASON_TICK, now_s, None)

    def run(self, stop: threading.Event, duration_s: float | None = None) -> None:
        """Loop until ``stop`` is set (or ``duration_s`` passes)."""
        period = self.cfg.slave.period_s
        self.t_start_s = t_next = self.clock()
        t_prev = t_next
        while not stop.is_set():
            now = self.clock()
            if duration_s is not None and now - self.t_start_s >= duration_s:
                break
            while now < t_next:
                ready = wait_readable(self.sock.sock, t_next, self.clock)
                now = self.clock()
                if ready:
                    while True:
                        try:
                            frames = self.sock.sock.recv_multipart(zmq.NOBLOCK)
                        except zmq.Again:
                            break
                        self._on_message(frames, self.clock())
            self.tick(now, min(max(now - t_prev, 1e-4), 0.05))
            self.sock.poll_monitor()
            t_prev = now
            # Late ticks catch up at half a period at the least (never back to back: the
            # limiter's step must span real time), and a starved loop skips ahead.
            t_next += period
            if now - t_next > 0.05:  # starved (e.g. CI load): skip ahead, don't burst
                t_next = now + period
            t_next = max(t_next, now + 0.5 * period)
        self.t_end_s = self.clock()

    def report(self) -> dict:
        """The slave's own counts (the MAE report is the master's)."""
        return {
            "robot": self.arm.name,
            "duration_s": round(self.t_end_s - self.t_start_s, 3),
            "messages": self.counts["messages"],
            "malformed": self.counts["malformed"],
            "received": self.counts["received"],
            "accepted": self.counts["accepted"],
            "dropped": dict(self.admission.dropped),
            "takeovers": self.admission.takeovers,
            "operator_holds": self.counts["operator_holds"],
            "stopped": self.stopped,
            "watchdog_trips": self.watchdog.trips,
            # Per trip: last valid sample -> the tick before the trip; at most watchdog_s
            # when every trip (and release of the arm) came at the first tick past it.
            "watchdog_pre_trip_max_s": round(max(self.watchdog.pre_trip_checks_s,
                                                 default=0.0), 4),
            "nonfinite_targets": self.counts["nonfinite_targets"],
            "box_clamped_ticks": self.limiter.clamped,
            "arm_faults": self.counts["arm_faults"],
            "auth_denied": LoggingAuthenticator.denied,
            "handshakes_failed": dict(self.sock.handshakes_failed),
        }


def make_arm(cfg: TeleopConfig) -> Arm:
    """The arm named by ``cfg.slave.robot``."""
    mapping = Mapping(cfg.mapping)
    if cfg.slave.robot == "sim":
        return SimArm(cfg.slave.sim_joint_speed_rad_s, lag_s=0.002,
                      tool_down=tuple(mapping.tool_down()))
    if cfg.slave.robot == "ur":
        # lazy: loads scipy.spatial, which the sim arm does not need
        from teleop.slaves.ur import URArm
        return URArm(cfg.slave, tool_down=tuple(mapping.tool_down()))
    raise ValueError(f"slave.robot must be 'sim' or 'ur', got {cfg.slave.robot!r}")


class SlaveThread:
    """A slave running in a thread of this process (the demo; tests). Context manager."""

    def __init__(self, cfg: TeleopConfig | None = None, bind: str = "tcp://127.0.0.1:*",
                 arm: Arm | None = None) -> None:
        self.cfg = cfg or TeleopConfig()
        self.arm = arm or make_arm(self.cfg)
        self.sock = SlaveSocket(bind, self.cfg.link)
        self.endpoint = self.sock.endpoint
        self._stop = threading.Event()
        self.loop: SlaveLoop | None = None
        self._thread: threading.Thread | None = None

    def __enter__(self) -> SlaveThread:
        try:
            self.arm.start(Mapping(self.cfg.mapping).to_robot(np.zeros(3)))
            self.loop = SlaveLoop(self.arm, self.sock, self.cfg)
        except Exception:
            self.arm.close()
            self.sock.close()
            raise
        self._thread = threading.Thread(target=self.loop.run, args=(self._stop,),
                                        name="teleop-slave", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        self.arm.close()
        self.sock.close()
