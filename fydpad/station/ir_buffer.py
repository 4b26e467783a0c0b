"""The IR samples between two vision frames, handed from the sensor loop to the vision
loop through a bounded ring.

The board samples at 100-1000 Hz, the camera at 10-30 Hz: the vision loop filters every
sample that arrived since its last frame (``vision.stream.LiveIndentation``), not just
the newest. The ring is bounded: a vision loop that stalls longer than the ring holds
loses the oldest samples (counted in ``lost``; the newest are kept), never the sensor
loop's time or the station's memory.
"""

from __future__ import annotations

import threading

import numpy as np
from numpy.typing import NDArray

#: 4 s at a 1 kHz board, 41 s at 100 Hz: far more than a frame's worth.
DEFAULT_CAPACITY = 4096


class IRBuffer:
    """A ring of ``(t_s, v0, v1, v2)`` rows: one writer (:meth:`push`, per sample) and one
    reader (:meth:`drain`, per frame), under a lock held for a row's copy or a slice's."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY):
        if capacity < 1:
            raise ValueError(f"IR buffer capacity {capacity}: must be at least 1")
        self.capacity = int(capacity)
        self._rows = np.zeros((self.capacity, 4))
        self._written = 0  # rows pushed since the start
        self._read = 0  # rows handed to the reader or lost
        #: Samples overwritten before the reader took them (the oldest go first).
        self.lost = 0
        #: Samples handed to the reader.
        self.drained = 0
        self._lock = threading.Lock()

    def push(self, t_s: float, volts: tuple[float, float, float]) -> None:
        """One sample (NaN volts where invalid)."""
        with self._lock:
            self._rows[self._written % self.capacity] = (t_s, *volts)
            self._written += 1

    def drain(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The samples pushed since the last drain, oldest first: ``(t_s[n], volts[n, 3])``
        (copies). If more than ``capacity`` came, only the newest ``capacity``."""
        with self._lock:
            n = self._written - self._read
            if n > self.capacity:
                self.lost += n - self.capacity
                n = self.capacity
            start = (self._written - n) % self.capacity
            if start + n <= self.capacity:
                out = self._rows[start:start + n].copy()
            else:  # wrapped: the tail of the array, then its head
                out = np.concatenate([self._rows[start:], self._rows[:start + n - self.capacity]])
            self._read = self._written
            self.drained += n
        return out[:, 0], out[:, 1:]

    def stats(self) -> dict:
        return {"capacity": self.capacity, "drained": self.drained, "lost": self.lost}
