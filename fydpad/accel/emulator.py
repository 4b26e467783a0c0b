"""An emulated accelerometer board speaking docs/accel_protocol.md on a pseudo-terminal,
so the real reader (:class:`fydpad.accel.serial.SerialAccelerometer`) is tested end to
end over a real tty.

It is a :class:`vision.serial_line.PtyEmulator` (pty, streaming thread, ``send`` of raw
bytes, ``pause``, ``unplug``, bytes the reader does not take in time dropped like a UART
without flow control), as the sensor board's emulator is, with the accelerometer's lines:
it streams a signal in m/s^2, quantised to the part's counts. ``skip`` loses samples on
the device (a FIFO overrun), ``restart`` is a device reset (counter and clock restart).
With ``clocked``, the part samples on its own clock like the real one and sends what its
FIFO holds (``fifo_depth``, the ADXL345's 32) when the thread gets to it: a starved
emulator thread (a loaded machine) sends late bursts, and loses, as counted gaps, only
what overflowed the FIFO, instead of slowing its device clock down.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from fydpad.accel.serial import G_M_S2, accel_data_line, accel_hello_line
from vision.serial_line import PtyEmulator

Signal = Callable[[int], tuple[float, float, float]]


def looped(signal_m_s2: ArrayLike) -> Signal:
    """Sample k of an ``(n, 3)`` array in m/s^2, repeating it."""
    a = np.asarray(signal_m_s2, dtype=np.float64).reshape(-1, 3)
    return lambda k: (float(a[k % len(a), 0]), float(a[k % len(a), 1]),
                      float(a[k % len(a), 2]))


def _at_rest(k: int) -> tuple[float, float, float]:
    return 0.0, 0.0, G_M_S2  # lying flat, face up


class AccelEmulator(PtyEmulator):
    """A 3-axis MEMS part behind a microcontroller on a pty; ``port`` is the path to open.

    ``signal`` is ``(n, 3)`` m/s^2 (looped) or ``k -> (ax, ay, az)``. Default part: an
    ADXL345 at +-16 g full resolution (3900 ug/LSB) at 1 kHz. Sample k carries counter
    ``(counter0 + k) mod 2^16`` and time ``start_us + k * 1e6 / rate_hz`` (mod 2^32).
    """

    def __init__(self, signal: ArrayLike | Signal = _at_rest, rate_hz: float = 1000.0,
                 ug_per_lsb: float = 3900.0, range_g: float = 16.0, part: str = "ADXL345",
                 start_us: int = 0, counter0: int = 0, hello_on_start: bool = True,
                 clocked: bool = False, fifo_depth: int = 32) -> None:
        fn = signal if callable(signal) else looped(signal)
        super().__init__(rate_hz=rate_hz, hello_on_start=hello_on_start)
        self.signal_fn: Signal = fn
        self.ug_per_lsb = float(ug_per_lsb)
        self.range_g = float(range_g)
        self.part = part
        self.start_us = int(start_us)
        self.counter0 = int(counter0)
        self.clocked = bool(clocked)
        if int(fifo_depth) < 1:
            raise ValueError(f"fifo_depth {fifo_depth}: must be at least one sample")
        self.fifo_depth = int(fifo_depth)
        self._t0_s: float | None = None

    def start(self, streaming: bool = True) -> AccelEmulator:
        self._t0_s = time.monotonic()
        super().start(streaming)
        return self

    def sample_time_s(self, k: int) -> float:
        """The monotonic time at which sample k is due on the device's clock (``clocked``,
        after ``start``): when a real part latches it, however late it is sent."""
        if self._t0_s is None:
            raise RuntimeError("sample_time_s before start()")
        return self._t0_s + k / self.rate_hz

    def send_sample(self, k: int | None = None) -> None:
        if k is not None or not self.clocked or self._t0_s is None:
            super().send_sample(k)
            return
        with self._lock:
            # Every sample latched on the device's clock since the last send, as a FIFO
            # drains: never one before its time (that gave an older value a later time,
            # 1.2-1.4 ms early by a varying amount), and a late thread loses only what
            # overflowed the FIFO.
            due = int((time.monotonic() - self._t0_s) * self.rate_hz)
            if due < self.k:
                return
            self.k = max(self.k, due - self.fifo_depth + 1)
            lines = [self._line(j) for j in range(self.k, due + 1)]
            self.k = due + 1
            self._write(b"".join(lines))

    @property
    def lsb_m_s2(self) -> float:
        return self.ug_per_lsb * 1e-6 * G_M_S2

    def counts(self, k: int) -> tuple[int, int, int]:
        """Sample k as the part's counts: rounded, clipped at its range."""
        full = round(self.range_g * 1e6 / self.ug_per_lsb)
        c = [min(full, max(-full, round(a / self.lsb_m_s2))) for a in self.signal_fn(k)]
        return c[0], c[1], c[2]

    def skip(self, n: int) -> None:
        """Lose the next ``n`` samples on the device (its FIFO overran): never sent."""
        with self._lock:
            self.k += n

    def restart(self) -> None:
        """A device reset: hello line, then counter and clock from zero."""
        with self._lock:
            self.k = 0
            self.start_us = 0
            self.counter0 = 0
            if self._t0_s is not None:  # the device's clock restarts with its counter
                self._t0_s = time.monotonic()
            self._write(self._hello())

    def _hello(self) -> bytes:
        return accel_hello_line(self.rate_hz, self.ug_per_lsb, self.range_g, self.part)

    def _line(self, k: int) -> bytes:
        t_us = self.start_us + round(k * 1e6 / self.rate_hz)
        return accel_data_line(self.counter0 + k, t_us, self.counts(k))
