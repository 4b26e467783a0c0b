"""Finger speed from the contact centroid stream (paper section III-B, Fig. 9).

The centroid is differentiated on-line and the speed low-passed at 10 Hz. The filter
is a first-order low-pass discretised for the actual sample interval, so irregular
frame times (dropped frames, ``frames.csv``) are handled. :class:`CentroidSpeed` turns
the camera-rate centroids into a speed for every 1 kHz render tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class SpeedState:
    """Filter state: the last sample and the filtered velocity (mm/s)."""

    t_s: float = math.nan
    x_mm: float = math.nan
    y_mm: float = math.nan
    vx_mm_s: float = 0.0
    vy_mm_s: float = 0.0


def speed_update(
    state: SpeedState, t_s: float, x_mm: float, y_mm: float, contact: bool,
    cutoff_hz: float = 10.0,
) -> tuple[float, SpeedState]:
    """One step: the low-passed speed (mm/s) and the new state.

    Without contact, or on the first sample of a contact, the speed is 0 and the filter
    restarts: a finger landing somewhere else is not a jump at infinite speed.
    """
    if not contact or not math.isfinite(x_mm) or not math.isfinite(state.x_mm):
        new = SpeedState(t_s, x_mm, y_mm, 0.0, 0.0) if contact else SpeedState()
        return 0.0, new
    dt = t_s - state.t_s
    if dt <= 0:
        return math.hypot(state.vx_mm_s, state.vy_mm_s), state
    vx = (x_mm - state.x_mm) / dt
    vy = (y_mm - state.y_mm) / dt
    alpha = 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * dt)
    fvx = state.vx_mm_s + alpha * (vx - state.vx_mm_s)
    fvy = state.vy_mm_s + alpha * (vy - state.vy_mm_s)
    return math.hypot(fvx, fvy), SpeedState(t_s, x_mm, y_mm, fvx, fvy)


@dataclass
class CentroidSpeed:
    """Finger speed for every 1 kHz tick from the camera-rate contact centroid.

    ``position(t_s, x_mm, y_mm, contact)`` at each camera frame differentiates the
    centroid (``vision.speed.speed_update``, whose own low-pass we bypass with a high
    cutoff); ``tick(dt_s)`` at 1 kHz holds that raw velocity between frames (i.e. it
    extrapolates the position linearly) and applies the paper's 10 Hz low-pass at the
    tick rate, so the speed is smooth rather than a 30 Hz staircase.

    ``sample(t_s, x_mm, y_mm, contact)`` takes the newest centroid at every tick (held
    between frames, as the station's render loop sees it): a changed one is a new frame,
    differentiated once; one unchanged for ``rest_after_s`` is a finger at rest (without
    that, ``tick`` would hold the last frame's velocity for ever).
    """

    cutoff_hz: float = 10.0
    #: Longer than a frame period at the slowest vision rate (the paper's 10 Hz).
    rest_after_s: float = 0.25
    contact: bool = False
    _last_x_mm: float = math.nan
    _last_y_mm: float = math.nan
    _last_contact: bool = False
    _t_new_s: float = -math.inf
    _state: SpeedState | None = None
    _vx: float = 0.0
    _vy: float = 0.0
    _fx: float = 0.0
    _fy: float = 0.0

    def position(self, t_s: float, x_mm: float, y_mm: float, contact: bool) -> None:
        state = self._state or SpeedState()
        was = self.contact and math.isfinite(state.x_mm)
        _, new = speed_update(state, t_s, x_mm, y_mm, contact, cutoff_hz=1e9)
        self._state = new
        self.contact = bool(contact)
        if not contact:
            self._vx = self._vy = self._fx = self._fy = 0.0
        elif was:
            self._vx, self._vy = new.vx_mm_s, new.vy_mm_s

    def sample(self, t_s: float, x_mm: float, y_mm: float, contact: bool) -> None:
        """The newest centroid at a tick: :meth:`position` once per new frame; a zero
        velocity once it has stayed put for ``rest_after_s``."""
        # Without contact the position is NaN: only the change to "no contact" is news.
        if contact != self._last_contact or (
                contact and (x_mm != self._last_x_mm or y_mm != self._last_y_mm)):
            self.position(t_s, x_mm, y_mm, contact)
            self._last_x_mm, self._last_y_mm, self._last_contact = x_mm, y_mm, contact
            self._t_new_s = t_s
        elif contact and t_s - self._t_new_s >= self.rest_after_s:
            # At rest; the next frame is still differentiated from the last real one (a
            # new time base here would divide its step by too short a time).
            self._vx = self._vy = 0.0

    def tick(self, dt_s: float = 1e-3) -> float:
        """Advance the low-pass by ``dt_s``; the filtered speed in mm/s (0 without contact)."""
        if not self.contact:
            return 0.0
        a = 1.0 - math.exp(-2.0 * math.pi * self.cutoff_hz * dt_s)
        self._fx += a * (self._vx - self._fx)
        self._fy += a * (self._vy - self._fy)
        return math.hypot(self._fx, self._fy)
