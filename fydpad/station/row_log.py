"""A CSV log written off the 1 kHz loop: the loop pushes each row into a preallocated
ring (:class:`fydpad.channels.ring.RowRing`), a thread of its own formats and writes.

The loop never formats, never writes, never waits: a full ring drops the row and counts
it (``stats``: ``dropped``), so a disk that stalls longer than the ring holds loses rows
that are counted and reported, never the tick. The ring holds ``buffer_s`` (2.5 s at
1 kHz by default) of rows, so an ordinary disk stall loses nothing. The thread wakes every
``poll_s``, writes what is there in one ``write`` and hands it to the OS at least every
0.5 s (:class:`vision.recording.CsvRowWriter`).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fydpad.channels.ring import RowRing
from vision.recording import CsvRowWriter

#: Seconds of rows the ring holds: more than the 2 s a disk may stall without a loss.
DEFAULT_BUFFER_S = 2.5


class RingRowLog:
    """``write(*values)`` from the loop (one row of ``columns``), ``close`` at the end.

    ``integer_columns`` are written as integers (a frame index). ``path`` may be a pipe
    (a FIFO): the tests throttle the writer with a reader that sleeps."""

    def __init__(self, path: str | Path, columns: Sequence[str], rate_hz: float,
                 buffer_s: float = DEFAULT_BUFFER_S, integer_columns: Sequence[str] = (),
                 poll_s: float = 0.02) -> None:
        self.path = Path(path)
        self.columns = tuple(columns)
        self.ring = RowRing(len(self.columns), max(1, math.ceil(buffer_s * rate_hz)))
        self.buffer_s = float(buffer_s)
        self._int_cols = [self.columns.index(c) for c in integer_columns]
        self.poll_s = float(poll_s)
        self._writer = CsvRowWriter(self.path, self.columns)  # open errors: here, at once
        self.n_written = 0
        #: The first failed write (rows after it are counted in ``lost_after_error``).
        self.error: BaseException | None = None
        self.lost_after_error = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="commands-log", daemon=True)
        self._thread.start()

    def write(self, *values: float) -> None:
        """One row into the ring; never blocks (a full ring drops it, counted)."""
        self.ring.push(*values)

    def _run(self) -> None:
        # Small chunks: the thread formats under the GIL, and the loop must not wait long
        # for it (the render process also shortens the GIL's switch interval).
        chunk = np.empty((max(1, min(self.ring.capacity, 32)), self.ring.width))
        while True:
            stopping = self._stop.is_set()
            n = self.ring.pop_into(chunk)
            if n:
                self._write(chunk[:n])
                time.sleep(0)  # let a waiting tick take the GIL between chunks
                continue
            if stopping:
                break
            self._stop.wait(self.poll_s)
        try:
            self._writer.close()
        except BaseException as exc:
            self.error = self.error or exc

    def _write(self, rows: np.ndarray) -> None:
        if self.error is not None:
            self.lost_after_error += len(rows)
            return
        out = rows.tolist()
        for j in self._int_cols:
            for r in out:
                v = r[j]
                r[j] = int(v) if math.isfinite(v) else None
        try:
            self._writer.write_rows(out)
        except BaseException as exc:
            self.error = exc
            self.lost_after_error += len(rows)
            return
        self.n_written += len(rows)

    def close(self, timeout_s: float = 10.0) -> None:
        """Write what the ring holds, close the file. RuntimeError naming the file for a
        failed write or close, or a write still stalled after ``timeout_s``."""
        self._stop.set()
        self._thread.join(timeout=timeout_s)
        if self._thread.is_alive():
            raise RuntimeError(f"{self.path}: still writing after {timeout_s:g} s "
                               f"({self.ring.level} rows not yet written)")
        if self.error is not None:
            raise RuntimeError(f"{self.path}: {self.error} ({self.lost_after_error} rows "
                               "not written)")

    def stats(self) -> dict:
        r = self.ring
        out = {"rows": r.n_pushed + r.n_dropped, "written": self.n_written,
               "dropped": r.n_dropped, "buffer_s": self.buffer_s,
               "peak_buffered": r.peak_level}
        if self.error is not None:
            out["error"] = str(self.error)
            out["lost_after_error"] = self.lost_after_error
        return out
