"""The accelerometer interface every backend implements.

A backend delivers samples as an ``(n, 4)`` float array: ``t_s, ax_m_s2, ay_m_s2,
az_m_s2`` with ``t_s`` on the device's clock (seconds, monotonic). ``read`` returns
whatever arrived since the last call (possibly zero rows) and never blocks longer than
its ``timeout_s``; a device that stops streaming raises :class:`AccelError` naming it.
"""

from __future__ import annotations

from types import TracebackType
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from vision.errors import DeviceFault

#: Column names of an accelerometer block.
ACCEL_COLUMNS = ("t_s", "ax_m_s2", "ay_m_s2", "az_m_s2")


class AccelError(DeviceFault, RuntimeError):
    """An accelerometer fault; the message names the device and what to check."""

    device = "accelerometer"
    check = "its cable, its power and the [accel] section of the configuration"


class Accelerometer(Protocol):
    """A 3-axis accelerometer on the fabric."""

    #: Nominal sample rate, Hz.
    rate_hz: float

    def connect(self) -> None:
        """Open the device and start streaming."""

    def read(self, timeout_s: float = 0.1) -> NDArray[np.float64]:
        """Samples since the last call, ``(n, 4)``: t_s, ax, ay, az (m/s^2)."""

    def disconnect(self) -> None:
        """Stop streaming and close; safe to call twice."""

    def __enter__(self) -> Accelerometer: ...

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None: ...
