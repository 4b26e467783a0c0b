"""Replay an accelerometer recording (CSV ``t_s,ax_m_s2,ay_m_s2,az_m_s2``) as a device.

``read`` returns the rows whose time since the first row is <= the wall time since
``connect`` times ``speed`` (``speed=inf``: everything that is left, in one block).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from types import TracebackType

import numpy as np
from numpy.typing import NDArray

from fydpad.accel.base import ACCEL_COLUMNS, AccelError
from vision.recording import RecordingError, csv_data_line, read_csv_columns


def read_accel_csv(path: str | Path) -> NDArray[np.float64]:
    """The ``(n, 4)`` array of a CSV; AccelError names file, line and field on bad rows."""
    try:
        cols = read_csv_columns(path, ACCEL_COLUMNS)
    except RecordingError as exc:
        raise AccelError(str(exc)) from None
    data = np.column_stack([cols[c] for c in ACCEL_COLUMNS])
    bad = np.flatnonzero(np.diff(data[:, 0]) <= 0)
    if bad.size:
        # diff index i compares data rows i and i + 1: the later one is at fault.
        line = csv_data_line(path, int(bad[0]) + 1)
        raise AccelError(f"{path}: line {line}: column 't_s' does not increase")
    return data


class ReplayAccelerometer:
    """An :class:`~fydpad.accel.base.Accelerometer` fed from a CSV file."""

    def __init__(self, path: str | Path, speed: float = 1.0) -> None:
        self.path = Path(path)
        self.speed = float(speed)
        self._data = read_accel_csv(self.path)
        dt = np.diff(self._data[:, 0])
        self.rate_hz = float(1.0 / np.median(dt)) if dt.size else math.nan
        self._pos = 0
        self._t0: float | None = None

    @property
    def finished(self) -> bool:
        return self._pos >= len(self._data)

    def connect(self) -> None:
        self._t0 = time.monotonic()

    def read(self, timeout_s: float = 0.1) -> NDArray[np.float64]:
        if self._t0 is None:
            raise AccelError(f"replay:{self.path}: read before connect()")
        if math.isinf(self.speed):
            end = len(self._data)
        else:
            elapsed_s = (time.monotonic() - self._t0) * self.speed
            t_rel = self._data[:, 0] - self._data[0, 0]
            end = int(np.searchsorted(t_rel, elapsed_s, side="right"))
        block = self._data[self._pos:end].copy()
        self._pos = max(self._pos, end)
        return block

    def disconnect(self) -> None:
        self._t0 = None

    def __enter__(self) -> ReplayAccelerometer:
        self.connect()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.disconnect()
