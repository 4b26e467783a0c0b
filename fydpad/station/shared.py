"""Latest-value hand-off between the station's loops and its render process.

A writer publishes the newest value; readers take the newest whenever they tick. Nothing
queues and nothing blocks: a seqlock over a small shared array of doubles (the writer
makes the sequence odd while writing; a reader retries if it saw an odd or a changed
sequence), so the 1 kHz render process never waits on the vision loop.
"""

from __future__ import annotations

import math
import time
from multiprocessing.sharedctypes import RawArray

import numpy as np
from numpy.typing import NDArray

from vision.state import FingerState

#: Layout of the shared finger state, after the sequence number at index 0.
STATE_FIELDS = ("t_s", "contact", "x_mm", "y_mm", "indentation_mm", "speed_mm_s", "force_n",
                "arrival_s", "frame")


class SharedRecord:
    """A fixed set of named doubles in shared memory, written by one writer.

    One writer only: two writers' read-modify-writes lose each other's changes and can
    leave the sequence odd. Where several threads change a record, they go through one
    lock-protected writer (``Station.set_control``).
    """

    def __init__(self, fields: tuple[str, ...], raw=None):
        self.raw = raw if raw is not None else RawArray("d", len(fields) + 1)
        self._init_local(fields)
        if raw is None:
            # Only a new record starts empty: one attached in another process must not
            # overwrite what the writer already published.
            self._view[1:] = math.nan

    def _init_local(self, fields: tuple[str, ...]) -> None:
        self.fields = fields
        self.index = {f: i for i, f in enumerate(fields)}
        self._view = np.frombuffer(self.raw, dtype=np.float64)
        # Two buffers: a read copies into the spare one and swaps only when consistent, so
        # the last consistent values survive a torn or timed-out read.
        self._buf = np.full(len(fields), math.nan)
        self._spare = np.empty(len(fields), np.float64)
        self._seq = 0
        #: Reads that gave up (``timeout_s``) and returned the last consistent values.
        self.stale_reads = 0

    def __reduce__(self):
        return (SharedRecord._attach, (self.fields, self.raw))

    @staticmethod
    def _attach(fields, raw) -> SharedRecord:
        rec = SharedRecord.__new__(SharedRecord)
        rec.raw = raw
        rec._init_local(fields)
        return rec

    @property
    def seq(self) -> int:
        return int(self._view[0]) // 2

    def write(self, values: NDArray[np.float64] | list[float]) -> None:
        new = np.asarray(values, dtype=np.float64)
        if new.shape != (len(self.fields),):  # checked before the sequence goes odd
            raise ValueError(f"{len(self.fields)} values expected ({', '.join(self.fields)}),"
                             f" got shape {new.shape}")
        v = self._view
        v[0] += 1.0  # odd: writing
        try:
            v[1:] = new
        finally:
            v[0] += 1.0  # even: consistent

    def read(self, timeout_s: float | None = None) -> tuple[int, NDArray[np.float64]]:
        """The newest consistent values (a reused buffer: copy to keep) and their sequence.

        ``timeout_s``: give up after it when no consistent read comes (a writer stopped
        mid-write: descheduled, or its process killed there) and return the last
        consistent values and sequence (seq 0: none yet), counted in ``stale_reads``;
        None: retry until one comes (a reader in the writer's own process)."""
        v = self._view
        spins = 0
        deadline = math.inf
        while True:
            s1 = v[0]
            if not int(s1) % 2:
                np.copyto(self._spare, v[1:])
                if v[0] == s1:
                    self._buf, self._spare = self._spare, self._buf
                    self._seq = int(s1) // 2
                    return self._seq, self._buf
            if timeout_s is not None:
                spins += 1
                if spins % 32 == 1:  # the clock costs more than a retry
                    now = time.perf_counter()
                    if deadline == math.inf:
                        deadline = now + timeout_s
                    elif now >= deadline:
                        self.stale_reads += 1
                        return self._seq, self._buf


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
