"""Finger speed from the contact centroid stream (paper section III-B, Fig. 9).

The centroid is differentiated on-line and the speed low-passed at 10 Hz. The filter
is a first-order low-pass discretised for the actual sample interval, so irregular
frame times (dropped frames, ``frames.csv``) are handled.
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
