"""Drive the chain and read the fabric: the measurement half of identification.

A signal in duty units (the vibration term of eq. 3) goes through a
:class:`~fydpad.motors.drive.MotorDrive` one tick at a time (the simulated plant, or the
QB board paced at the render rate) while an :class:`~fydpad.accel.base.Accelerometer`
on the fabric streams. The accelerometer's samples are put on the ticks' clock: the
clock offset is the smallest (read time - newest sample time) over the reads, i.e. the
read with the least transport delay; on the simulated plant both clocks are the plant's
``t_s`` and the offset is exactly zero.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.accel.base import AccelError
from fydpad.chain import ChainError

Array = NDArray[np.float64]

#: Accelerometer columns: t_s, ax, ay, az.
AXES = {"x": 1, "y": 2, "z": 3}


@dataclass(frozen=True)
class ChainRun:
    """One drive of the chain: what was commanded and what the fabric did, tick by tick."""

    #: The vibration term the plant was given, duty (eq. 3), and the fabric's acceleration
    #: on the chosen axis (m/s^2), paired at the drive's rate (:func:`on_accel_grid`).
    x_duty: Array
    y_m_s2: Array
    #: Eq. 3 vibration clips during the run (0: x_duty is what the motors got).
    vibration_clips: int
    #: Load-cell readings during the run (N), one per accelerometer read.
    force_n: Array


def settle(drive, ticks: int) -> None:
    """Hold the drive's current position target, no vibration, for ``ticks`` ticks."""
    for _ in range(ticks):
        drive.tick(0.0)


def drive_signal(
    drive, accel, x_duty: Array, clock: Callable[[], float], axis: str = "x",
    pace: Callable[[], object] | None = None, force: Callable[[], float] | None = None,
    read_every: int = 50, stall_s: float = 0.5, progress: Callable[[int], None] | None = None,
    what: str = "chain",
) -> ChainRun:
    """Command ``x_duty`` as eq. 3's vibration term, one value per tick, and read the
    accelerometer (connected by the caller) every ``read_every`` ticks. ``clock`` gives
    the time at the end of a tick on the accelerometer's time base before offsetting
    (the plant's ``t_s``; the host clock on the real device), ``pace`` waits for the next
    tick on the real device. ChainError when the accelerometer stops for ``stall_s``."""
    comp = drive.composer
    col = AXES[axis]
    rate_hz = drive.config.rate_hz
    per_duty = 1.0 / comp.config.vibration_duty_per_unit
    gain = comp.gain
    comp.gain = 1.0  # x_duty is in duty units: the per-texture gain is not part of it
    clips0 = comp.vibration_clips
    n = len(x_duty)
    t_tick = np.empty(n)
    blocks: list[Array] = []
    forces: list[float] = []
    offset = math.inf
    got = 0
    last_new_tick = 0
    stall_ticks = max(int(stall_s * rate_hz), read_every)

    def read(k: int) -> None:
        nonlocal offset, got, last_new_tick
        try:
            b = accel.read(0.0)
        except AccelError as exc:
            raise ChainError(f"{what}: accelerometer: {exc}") from None
        now = clock()
        if len(b):
            blocks.append(b)
            got += len(b)
            last_new_tick = k
            offset = min(offset, now - float(b[-1, 0]))
        elif k - last_new_tick >= stall_ticks:
            raise ChainError(f"{what}: the accelerometer stopped: nothing for "
                             f"{(k - last_new_tick) / rate_hz:.2f} s after {got} samples; "
                             "check its cable, power and --accel")
        if force is not None:
            forces.append(force())

    try:
        for k in range(n):
            if pace is not None:
                pace()
            drive.tick(float(x_duty[k]) * per_duty)
            t_tick[k] = clock()
            if (k + 1) % read_every == 0:
                read(k)
                if progress is not None:
                    progress(read_every)
        read(n)
        if pace is not None:
            # On the device the last ticks' samples are still on the wire (USB, the
            # reader's 10 ms port timeout): wait for them, up to ``stall_s``.
            deadline = time.monotonic() + stall_s
            while (blocks and float(blocks[-1][-1, 0]) + offset < t_tick[-1]
                   and time.monotonic() < deadline):
                time.sleep(0.002)
                read(n)
    finally:
        comp.gain = gain
    clips = comp.vibration_clips - clips0
    if not blocks:
        raise ChainError(f"{what}: the accelerometer sent nothing; check its cable, power "
                         "and --accel")
    acc = np.vstack(blocks)
    t_acc = acc[:, 0] + offset
    if t_acc[0] > t_tick[0] + 0.5 / rate_hz or t_acc[-1] < t_tick[-1] - 0.5 / rate_hz:
        raise ChainError(f"{what}: the accelerometer covered {t_acc[0]:.3f}-{t_acc[-1]:.3f} s "
                         f"of a {t_tick[0]:.3f}-{t_tick[-1]:.3f} s drive; check its rate "
                         "and clock")
    x, y = on_accel_grid(np.asarray(x_duty, np.float64), t_tick, t_acc, acc[:, col], rate_hz)
    return ChainRun(x, y, clips, np.asarray(forces))


def on_accel_grid(x_duty: Array, t_tick: Array, t_acc: Array, a: Array, rate_hz: float
                  ) -> tuple[Array, Array]:
    """The input and the response paired on the accelerometer's own samples.

    Interpolating the response at the ticks' times would low-pass it: a linear
    interpolation a random fraction of a sample away costs 1.6 / 3.8 / 7.3 dB at 200 /
    300 / 400 Hz. Instead, where the accelerometer samples at the drive's rate, each
    sample is paired with the command the plant was holding then (command k from the end
    of tick k, when it was sent, to the next); samples lost on the way are put back by
    interpolation (rare, and counted by the reader). On the simulated plant the two grids
    are the same and this is the identity. At another accelerometer rate the response is
    interpolated at the ticks' times as before.
    """
    inside = (t_acc >= t_tick[0]) & (t_acc <= t_tick[-1])
    t_y, y = t_acc[inside], a[inside]
    step = float(np.median(np.diff(t_y))) if t_y.size > 1 else 0.0
    if t_y.size < 2 or abs(step * rate_hz - 1.0) > 0.01:
        return x_duty, np.interp(t_tick, t_acc, a)
    n_u = round((t_y[-1] - t_y[0]) / step) + 1
    if n_u != t_y.size:  # lost samples: back on a uniform grid
        t_u = t_y[0] + np.arange(n_u) * step
        y = np.interp(t_u, t_y, y)
        t_y = t_u
    held = np.clip(np.searchsorted(t_tick, t_y, side="right") - 1, 0, x_duty.size - 1)
    return x_duty[held], y


def press_to_force(plant, force_n: float, tol_n: float = 1e-4) -> float:
    """The simulated finger: indent the plant until it pushes back with ``force_n``
    (bisection on the one fabric model's force law). Returns the indentation, mm."""
    lo, hi = 0.0, 50.0
    plant.set_indentation_mm(hi)
    if plant.force_n() < force_n:
        raise ChainError(f"simulated finger: {force_n:g} N is beyond a {hi:g} mm dent")
    while hi - lo > 1e-6:
        mid = 0.5 * (lo + hi)
        plant.set_indentation_mm(mid)
        if plant.force_n() < force_n:
            lo = mid
        else:
            hi = mid
        if abs(plant.force_n() - force_n) < tol_n:
            break
    return plant.indentation_mm


def check_force(force_n: Array, target_n: float, tolerance_n: float, what: str
                ) -> tuple[float, float]:
    """Mean and sd of the load cell over a run; ChainError when the mean is outside
    ``target_n +- tolerance_n`` (the finger did not hold the force) or when some reads
    have no force (a load cell that failed part way: its mean would not be the run's),
    ``nan`` without a load cell (every read NaN)."""
    finite = np.isfinite(force_n)
    if not finite.any():
        return math.nan, math.nan
    if not finite.all():
        raise ChainError(f"{what}: the load cell gave no force for {int((~finite).sum())} of "
                         f"{force_n.size} reads: check its cable and run again")
    f = force_n
    mean, sd = float(np.mean(f)), float(np.std(f))
    if abs(mean - target_n) > tolerance_n:
        raise ChainError(f"{what}: normal force {mean:.2f} +- {sd:.2f} N, outside "
                         f"{target_n:g} +- {tolerance_n:g} N: hold the finger steadier "
                         "(watch the load cell) and run again")
    return mean, sd
