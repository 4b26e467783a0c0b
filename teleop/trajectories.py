"""Analytic finger trajectories for demos, benchmarks and tests (paper IV-B trials).

Circle, Lissajous and tapping, at the paper's 30 fps, with optional measurement noise.
The true position is returned next to the noisy FingerState stream, so accuracy is
checked against ground truth.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from vision.state import FingerState

Truth = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


def circle(speed_mm_s: float = 40.0, radius_mm: float = 25.0,
           depth_mm: float = 5.0) -> Truth:
    """Constant-speed circle, constant indentation."""
    w = speed_mm_s / radius_mm

    def f(t: np.ndarray):
        c = np.ones_like(t, dtype=bool)
        return c, radius_mm * np.cos(w * t), radius_mm * np.sin(w * t), np.full_like(t, depth_mm)
    return f


def lissajous(max_speed_mm_s: float = 40.0, ax_mm: float = 35.0, ay_mm: float = 25.0,
              depth_mm: float = 5.0) -> Truth:
    """x = ax sin(w t), y = ay sin(2 w t + pi/4), w chosen so the peak speed is max_speed."""
    tt = np.linspace(0, 2 * math.pi, 4001)
    speed_per_w = np.max(np.hypot(ax_mm * np.cos(tt), 2 * ay_mm * np.cos(2 * tt + math.pi / 4)))
    w = max_speed_mm_s / speed_per_w

    def f(t: np.ndarray):
        c = np.ones_like(t, dtype=bool)
        x = ax_mm * np.sin(w * t)
        y = ay_mm * np.sin(2 * w * t + math.pi / 4)
        return c, x, y, np.full_like(t, depth_mm)
    return f


def tapping(peak_speed_mm_s: float = 80.0, press_s: float = 0.3, lift_s: float = 0.2,
            x_mm: float = 10.0, y_mm: float = -5.0) -> Truth:
    """Taps in place: z = D sin^2(pi t / press_s) while pressed, contact 0 in between.

    D follows from the peak indentation speed D * pi / press_s.
    """
    depth = peak_speed_mm_s * press_s / math.pi
    period = press_s + lift_s

    def f(t: np.ndarray):
        ph = np.mod(t, period)
        c = ph < press_s
        z = np.where(c, depth * np.sin(math.pi * ph / press_s) ** 2, 0.0)
        c = c & (z > 0.05)  # the pad sees contact once the fabric moves
        z = np.where(c, z, 0.0)
        return c, np.full_like(t, x_mm), np.full_like(t, y_mm), z
    return f


TRAJECTORIES: dict[str, Callable[[], Truth]] = {
    "circle": circle, "lissajous": lissajous, "tapping": tapping}


def finger_stream(truth: Truth, duration_s: float, fps: float = 30.0, noise_mm: float = 0.1,
                  seed: int = 0) -> tuple[list[FingerState], np.ndarray]:
    """Sample ``truth`` at ``fps`` with Gaussian noise; returns states and truth rows.

    The truth rows are ``t_s, contact, x_mm, y_mm, z_mm`` (the truth.csv columns).
    """
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration_s * fps)) / fps
    c, x, y, z = truth(t)
    states = []
    for i in range(t.size):
        if not c[i]:
            states.append(FingerState.no_contact(float(t[i])))
            continue
        nx, ny, nz = rng.normal(0.0, noise_mm, 3)
        states.append(FingerState(t_s=float(t[i]), contact=True, x_mm=float(x[i] + nx),
                                  y_mm=float(y[i] + ny), indentation_mm=float(z[i] + nz)))
    truth_rows = np.column_stack([t, c.astype(float), np.where(c, x, np.nan),
                                  np.where(c, y, np.nan), z])
    return states, truth_rows
