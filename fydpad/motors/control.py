"""The host position loop that gives eq. (3)'s input_POSITION (paper Fig. 7).

A PID per motor on the encoder angle, run at the render rate (1 kHz). The derivative
acts on the measurement (no kick when the softness reference steps); the integral
removes the steady offset the fabric's tension would otherwise leave (a stiffness is a
position, so an offset is a stiffness error); it is frozen while the output saturates
(anti-windup). Scalars only: nothing allocated per tick.
"""

from __future__ import annotations


class PositionLoop:
    """Two PIDs, reference and measurement in rad, output in duty (unclipped)."""

    def __init__(self, kp: float, ki: float, kd: float, dt_s: float,
                 output_limit: float) -> None:
        self.kp, self.ki, self.kd, self.dt_s = kp, ki, kd, dt_s
        self.output_limit = output_limit
        self.out = [0.0, 0.0]
        self.reset()

    def reset(self) -> None:
        self._integ = [0.0, 0.0]
        self._prev = [float("nan"), float("nan")]

    def update(self, ref0: float, ref1: float, meas0: float, meas1: float) -> list[float]:
        """One tick; writes and returns ``out`` (the two input_POSITION duties)."""
        self._one(0, ref0, meas0)
        self._one(1, ref1, meas1)
        return self.out

    def _one(self, i: int, ref: float, meas: float) -> None:
        prev = self._prev[i]
        rate = 0.0 if prev != prev else (meas - prev) / self.dt_s
        self._prev[i] = meas
        err = ref - meas
        integ = self._integ[i] + err * self.dt_s
        u = self.kp * err + self.ki * integ - self.kd * rate
        lim = self.output_limit
        if -lim < u < lim or (u >= lim and err < 0) or (u <= -lim and err > 0):
            self._integ[i] = integ  # anti-windup: integrate only when it can help
        self.out[i] = u
