"""Latest-value hand-off between the station's loops and its render process.

A writer publishes the newest value; readers take the newest whenever they tick. Nothing
queues and nothing blocks: a seqlock over a small shared array of doubles (the writer
makes the sequence odd while writing; a reader retries if it saw an odd or a changed
sequence), so the 1 kHz render process never waits on the vision loop.
"""

from __future__ import annotations

import math
import multiprocessing as mp
from multiprocessing.sharedctypes import RawArray

import numpy as np
from numpy.typing import NDArray

from vision.state import FingerState

#: Layout of the shared finger state, after the sequence number at index 0.
STATE_FIELDS = ("t_s", "contact", "x_mm", "y_mm", "indentation_mm", "speed_mm_s", "force_n",
                "arrival_s", "frame")


class SharedRecord:
    """A fixed set of named doubles in shared memory, written by one writer."""

    def __init__(self, fields: tuple[str, ...], raw=None):
        self.fields = fields
        self.index = {f: i for i, f in enumerate(fields)}
        self.raw = raw if raw is not None else RawArray("d", len(fields) + 1)
        self._view = np.frombuffer(self.raw, dtype=np.float64)
        if raw is None:
            # Only a new record starts empty: one attached in another process must not
            # overwrite what the writer already published.
            self._view[1:] = math.nan
        self._buf = np.empty(len(fields), np.float64)

    def __reduce__(self):
        return (SharedRecord._attach, (self.fields, self.raw))

    @staticmethod
    def _attach(fields, raw) -> SharedRecord:
        rec = SharedRecord.__new__(SharedRecord)
        rec.fields = fields
        rec.index = {f: i for i, f in enumerate(fields)}
        rec.raw = raw
        rec._view = np.frombuffer(raw, dtype=np.float64)
        rec._buf = np.empty(len(fields), np.float64)
        return rec

    @property
    def seq(self) -> int:
        return int(self._view[0]) // 2

    def write(self, values: NDArray[np.float64] | list[float]) -> None:
        v = self._view
        v[0] += 1.0  # odd: writing
        v[1:] = values
        v[0] += 1.0  # even: consistent

    def read(self) -> tuple[int, NDArray[np.float64]]:
        """The newest consistent values (a reused buffer: copy to keep) and their sequence."""
        v = self._view
        while True:
            s1 = v[0]
            if int(s1) % 2:
                continue
            np.copyto(self._buf, v[1:])
            if v[0] == s1:
                return int(s1) // 2, self._buf


class SharedFingerState(SharedRecord):
    """The latest :class:`FingerState` with the clock time its frame arrived."""

    def __init__(self, raw=None):
        super().__init__(STATE_FIELDS, raw)

    def __reduce__(self):
        return (SharedFingerState, (self.raw,))

    def publish(self, state: FingerState, arrival_s: float, frame: int) -> None:
        self.write([state.t_s, 1.0 if state.contact else 0.0, state.x_mm, state.y_mm,
                    state.indentation_mm, state.speed_mm_s, state.force_n, arrival_s,
                    float(frame)])

    def latest(self) -> tuple[int, FingerState | None]:
        seq, v = self.read()
        if seq == 0:
            return 0, None
        return seq, FingerState(t_s=v[0], contact=bool(v[1]), x_mm=v[2], y_mm=v[3],
                                indentation_mm=v[4], speed_mm_s=v[5], force_n=v[6])


def new_event() -> mp.synchronize.Event:
    return mp.get_context("spawn").Event()
