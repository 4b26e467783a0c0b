"""Slave-side safety: workspace box, speed/acceleration limits, watchdog.

Pure: the caller passes times in. Which samples are admitted is teleop/admission.py.
"""

from __future__ import annotations

import math

import numpy as np

from teleop.config import SafetyConfig


class MotionLimiter:
    """Turn a target into a command that respects the box and the speed/accel limits.

    Speed towards the target is also capped so that the command can stop in whole ticks
    at half the acceleration limit (about sqrt(a d), d: distance left): the limit is on
    the acceleration vector's norm, and the other half is left for turning the velocity
    that lies across the error (a touch-down moves x, y and z at once), so a far target
    is approached with braking, not overshoot.
    """

    def __init__(self, cfg: SafetyConfig, start_mm: np.ndarray) -> None:
        self.cfg = cfg
        self.box_min = np.asarray(cfg.box_min_mm, float)
        self.box_max = np.asarray(cfg.box_max_mm, float)
        if np.any(self.box_min >= self.box_max):
            raise ValueError(f"safety box min {cfg.box_min_mm} must be below max {cfg.box_max_mm}")
        self.cmd_mm = self.clamp(np.asarray(start_mm, float))
        self.vel_mm_s = np.zeros(3)
        self.speed_cap_mm_s = cfg.max_speed_mm_s
        self.clamped = 0  # ticks where the box changed the target
        self._prev_tgt: np.ndarray | None = None

    def clamp(self, p_mm: np.ndarray) -> np.ndarray:
        return np.clip(p_mm, self.box_min, self.box_max)

    def step(self, target_mm: np.ndarray, dt_s: float) -> np.ndarray:
        """One control tick towards ``target_mm``; returns the new command."""
        tgt = self.clamp(target_mm)
        if not np.array_equal(tgt, target_mm):
            self.clamped += 1
        # Feed-forward the target's own velocity (a moving finger), unless it jumped: the
        # braking law below then only acts on what is left, so tracking is not slowed.
        v_tgt = np.zeros(3) if self._prev_tgt is None else (tgt - self._prev_tgt) / dt_s
        if float(np.linalg.norm(v_tgt)) > self.speed_cap_mm_s:
            v_tgt = np.zeros(3)
        self._prev_tgt = tgt
        err = tgt - self.cmd_mm - v_tgt * dt_s
        dist = float(np.linalg.norm(err))
        a_max = self.cfg.max_accel_mm_s2
        v_des = v_tgt.copy()
        if dist > 1e-9:
            # Discrete-time braking speed: stopping in whole ticks lands on the target
            # instead of sqrt(2 a d), which overshoots by up to a dt^2. At half the limit:
            # the axes share it, and a 300 mm/s approach overshot by 2.4 mm with all of it.
            adt = 0.5 * a_max * dt_s  # half: the other axes may need the rest (coupled)
            v_brake = adt * (math.sqrt(0.25 + 2.0 * dist / (adt * dt_s)) - 0.5)
            v_des += err / dist * min(dist / dt_s, v_brake)
        speed = float(np.linalg.norm(v_des))
        if speed > self.speed_cap_mm_s:
            v_des *= self.speed_cap_mm_s / speed
        dv = v_des - self.vel_mm_s
        dv_norm = float(np.linalg.norm(dv))
        a_dt = a_max * dt_s
        if dv_norm > a_dt:
            # Axes slowing down brake first, the others share what is left: scaling the
            # whole vector let a depth swinging at a touch-down take the budget x needed
            # to stop (at 300 mm/s a re-engage passed its point in x by up to 0.8 mm;
            # docs/teleop.md, test_safety.py). Every axis slowing down counts, also one
            # already past its target (a depth going deeper): without a share it runs on.
            brake = dv * self.vel_mm_s < 0.0
            dv_b = np.where(brake, dv, 0.0)
            b_norm = float(np.linalg.norm(dv_b))
            if b_norm > a_dt:
                dv = dv_b * (a_dt / b_norm)
            else:
                rest = dv - dv_b
                room = math.sqrt(a_dt * a_dt - b_norm * b_norm)
                r_norm = float(np.linalg.norm(rest))
                dv = dv_b + (rest * (room / r_norm) if r_norm > room else rest)
        self.vel_mm_s = self.vel_mm_s + dv
        self.cmd_mm = self.clamp(self.cmd_mm + self.vel_mm_s * dt_s)
        return self.cmd_mm.copy()

    def hold(self, dt_s: float) -> np.ndarray:
        """Decelerate to rest within the acceleration limit, then stay."""
        self._prev_tgt = None
        v = float(np.linalg.norm(self.vel_mm_s))
        dv = self.cfg.max_accel_mm_s2 * dt_s
        self.vel_mm_s = np.zeros(3) if v <= dv else self.vel_mm_s * (1.0 - dv / v)
        self.cmd_mm = self.clamp(self.cmd_mm + self.vel_mm_s * dt_s)
        return self.cmd_mm.copy()


class Watchdog:
    """True while the last valid sample is younger than ``timeout_s`` (slave clock)."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self.last_valid_s = -math.inf
        self.trips = 0
        self.trip_delays_s: list[float] = []  # last valid sample -> hold, per trip
        # Per trip: last valid sample -> the check before the trip (<= timeout: the hold came
        # at the first check past the deadline, however late the scheduler ran it).
        self.pre_trip_checks_s: list[float] = []
        self._alive = False
        self._last_check_s = -math.inf

    def feed(self, now_s: float) -> None:
        self.last_valid_s = now_s

    def alive(self, now_s: float) -> bool:
        ok = now_s - self.last_valid_s <= self.timeout_s
        if self._alive and not ok:
            self.trips += 1
            self.trip_delays_s.append(now_s - self.last_valid_s)
            self.pre_trip_checks_s.append(self._last_check_s - self.last_valid_s)
        self._alive = ok
        self._last_check_s = now_s
        return ok
