"""The fabric accelerometer on a serial port: a microcontroller streaming a 3-axis MEMS
part at >= 1 kHz in the line protocol of docs/accel_protocol.md (pyserial).

The framing (``$payload*HH``, XOR checksum), the line splitter and the device clock are
the serial line transport's (:mod:`vision.serial_line`), as the sensor board's are; this
module adds the accelerometer's lines
and a reader that returns blocks. ``read`` never crashes on bad bytes: garbage, cut
lines and bad checksums are counted in ``stats`` and skipped, a gap in the sample
counter is counted as dropped samples, and a device that sends no valid sample for
``timeout_s`` raises :class:`~fydpad.accel.base.AccelError` naming the port.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.accel.base import AccelError
from vision.serial_line import (
    ChecksumError,
    DeviceClock,
    LineError,
    frame_line,
    take_line,
    unframe_line,
)

PROTOCOL_VERSION = 1
DEVICE_NAME = "FYDPAD-ACCEL"
#: 1 kHz of ~45-byte lines is ~450 kbit/s on the wire: 115200 baud is 4x too slow.
DEFAULT_BAUD = 921600
G_M_S2 = 9.80665
#: The sample counter is 16 bit: a gap of 65536 samples or more is not seen as one (the
#: stall timeout fires long before, 65 s at 1 kHz).
COUNTER_MOD = 2**16


def accel_data_line(n: int, t_us: int, counts: tuple[int, int, int]) -> bytes:
    """``$A,<n>,<t_us>,<x>,<y>,<z>*HH\\n``: sample counter, device microseconds, raw counts."""
    x, y, z = (int(c) for c in counts)
    return frame_line(f"A,{int(n) % COUNTER_MOD},{int(t_us) % 2**32},{x},{y},{z}")


def accel_hello_line(rate_hz: float, ug_per_lsb: float, range_g: float,
                     part: str = "MEMS") -> bytes:
    """``$H,FYDPAD-ACCEL,<version>,<rate_hz>,<ug_per_lsb>,<range_g>,<part>*HH\\n``."""
    return frame_line(f"H,{DEVICE_NAME},{PROTOCOL_VERSION},{rate_hz:g},{ug_per_lsb:g},"
                      f"{range_g:g},{part}")


@dataclass(frozen=True)
class AccelInfo:
    """From the device's hello line: rate and scale of the raw counts."""

    name: str
    version: int
    rate_hz: float
    ug_per_lsb: float
    range_g: float
    part: str

    @property
    def lsb_m_s2(self) -> float:
        return self.ug_per_lsb * 1e-6 * G_M_S2


class ForeignHello(LineError):
    """A hello line from another device (the sensor board, say): the wrong port."""

    def __init__(self, name: str) -> None:
        super().__init__(f"hello from {name!r}, not {DEVICE_NAME} (wrong port?)")
        self.name = name


@dataclass(frozen=True)
class AccelLine:
    n: int
    t_us: int
    counts: tuple[int, int, int]


def parse_accel_line(line: bytes) -> AccelLine | AccelInfo:
    """One line (without the newline) -> AccelLine or AccelInfo, or LineError."""
    fields = unframe_line(line)
    try:
        if fields[0] == "A" and len(fields) == 6:
            n, t_us = int(fields[1]), int(fields[2])
            if not (0 <= n < COUNTER_MOD and 0 <= t_us < 2**32):
                raise LineError("counter or time stamp out of range")
            return AccelLine(n, t_us, (int(fields[3]), int(fields[4]), int(fields[5])))
        if fields[0] == "H" and len(fields) == 7 and fields[1] == DEVICE_NAME:
            info = AccelInfo(fields[1], int(fields[2]), float(fields[3]), float(fields[4]),
                             float(fields[5]), fields[6])
            if not (info.rate_hz > 0 and info.ug_per_lsb > 0 and info.range_g > 0):
                raise LineError("hello with a rate, scale or range <= 0")
            return info
    except ValueError:
        raise LineError("a field is not a number") from None
    if fields[0] == "H" and len(fields) > 1:
        raise ForeignHello(fields[1][:20])
    raise LineError(f"unknown line type or field count ({fields[0][:8]!r}, {len(fields)})")


@dataclass
class AccelStats:
    """What the reader saw; bad lines are counted and skipped."""

    samples: int = 0
    hello: int = 0
    bad_checksum: int = 0
    malformed: int = 0
    overlong: int = 0
    #: Samples missing by the sample counter (device FIFO overrun, bytes lost on the link).
    dropped: int = 0
    #: Samples with a count at or beyond the part's range (clipped by the part).
    saturated: int = 0
    device_resets: int = 0
    last_error: str = ""

    @property
    def bad_lines(self) -> int:
        return self.bad_checksum + self.malformed + self.overlong


class SerialAccelerometer:
    """An :class:`~fydpad.accel.base.Accelerometer` on a serial port.

    ``connect`` opens the port, asks for the hello line (``?``) and waits for it up to
    ``timeout_s``: the counts' scale comes from it. ``read`` drains what arrived and
    returns it as ``(n, 4)``: t_s (device clock, from the first sample after connect),
    ax, ay, az in m/s^2. Read at least every ~50 ms at 1 kHz: the OS buffer is finite,
    and bytes lost there show up as malformed lines and dropped samples.
    """

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, timeout_s: float = 0.5,
                 serial_factory: Callable[..., Any] | None = None) -> None:
        self.port = port
        self.baud = int(baud)
        self.timeout_s = float(timeout_s)
        self.info: AccelInfo | None = None
        #: The name in another device's hello line, if one answered on this port.
        self.foreign_device = ""
        self.rate_hz = float("nan")  # from the hello line
        self.stats = AccelStats()
        self._factory = serial_factory
        self._ser: Any = None
        self._buf = bytearray()
        self._clock = DeviceClock(1e6)
        self._last_n: int | None = None
        self._last_valid_s = 0.0
        self._errors: tuple[type[BaseException], ...] = (OSError,)

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> None:
        import serial  # pyserial; imported here so replay and sim work without it

        self._errors = (serial.SerialException, OSError)
        factory = self._factory or serial.Serial
        try:
            # A short port timeout: read() keeps its own deadline and must not overrun it.
            self._ser = factory(self.port, self.baud, timeout=0.01, write_timeout=0.5)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise AccelError(f"{self.port}: cannot open the accelerometer ({exc})") from None
        try:
            self._ser.reset_input_buffer()  # stale bytes from before we opened
            self._ser.write(b"?\n")
        except self._errors as exc:
            self.disconnect()
            raise AccelError(f"{self.port}: accelerometer not responding ({exc})") from None
        self._buf.clear()
        self._clock = DeviceClock(1e6)
        self._last_n = None
        self.info = None
        try:
            self._wait_for_hello()
        except AccelError:
            self.disconnect()  # the port was opened here: a failed connect leaves it closed
            raise

    def _wait_for_hello(self) -> None:
        deadline = time.monotonic() + self.timeout_s
        while self.info is None:
            if time.monotonic() > deadline:
                seen = self.stats.samples + self.stats.bad_lines
                self.disconnect()
                what = (f"a {self.foreign_device} answered: wrong port?" if self.foreign_device
                        else f"is it {DEVICE_NAME} firmware at {self.baud} baud?")
                raise AccelError(f"{self.port}: no hello line from the accelerometer in "
                                 f"{self.timeout_s:g} s ({seen} other lines; {what})")
            # Data before the hello cannot be scaled; it is dropped (not counted as bad).
            self._pump(None)
        self._last_valid_s = time.monotonic()

    def disconnect(self) -> None:
        if self._ser is not None:
            try:
                self._ser.close()
            except self._errors:
                pass
            self._ser = None

    def __enter__(self) -> SerialAccelerometer:
        self.connect()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.disconnect()

    # ------------------------------------------------------------------ reading

    def read(self, timeout_s: float = 0.1) -> NDArray[np.float64]:
        """Samples since the last call, ``(n, 4)``; waits up to ``timeout_s`` for the first."""
        if self._ser is None:
            raise AccelError(f"serial:{self.port}: read before connect()")
        rows: list[tuple[float, float, float, float]] = []
        deadline = time.monotonic() + timeout_s
        while True:
            waiting = self._pump(rows)
            now = time.monotonic()
            if rows:
                self._last_valid_s = now
                if not waiting or now >= deadline:
                    break
            elif now - self._last_valid_s > self.timeout_s:
                raise AccelError(
                    f"{self.port}: no valid samples from the accelerometer for "
                    f"{self.timeout_s:g} s ({self.stats.bad_lines} bad lines so far; "
                    "is it powered and streaming?)")
            elif now >= deadline:
                break
        return np.array(rows, dtype=np.float64).reshape(-1, 4)

    def _pump(self, rows: list[tuple[float, float, float, float]] | None) -> int:
        """Read what the port has (or wait up to its 10 ms timeout), handle every complete
        line; returns the bytes still waiting. ``rows`` None: before the hello."""
        try:
            chunk = self._ser.read(max(1, min(self._ser.in_waiting, 65536)))
            self._buf += chunk
            while True:
                line, overlong = take_line(self._buf)
                self.stats.overlong += overlong
                if line is None:
                    break
                self._handle(line, rows)
            return int(self._ser.in_waiting)
        except self._errors as exc:
            raise AccelError(f"{self.port}: accelerometer disconnected ({exc})") from None

    def _handle(self, line: bytes, rows: list[tuple[float, float, float, float]] | None) -> None:
        if not line.strip():
            return
        try:
            parsed = parse_accel_line(line)
        except ChecksumError as exc:
            self.stats.bad_checksum += 1
            self.stats.last_error = str(exc)
            return
        except LineError as exc:
            if isinstance(exc, ForeignHello):
                self.foreign_device = exc.name
            self.stats.malformed += 1
            self.stats.last_error = f"{exc}: {line[:40]!r}"
            return
        if line.rfind(b"$") > 0:
            self.stats.malformed += 1  # a cut line ran into this one: its fragment is lost
        if isinstance(parsed, AccelInfo):
            self.info = parsed
            self.rate_hz = parsed.rate_hz
            self.stats.hello += 1
            # A hello mid-stream: the device restarted (counter and clock from zero),
            # whatever its next time stamp says (after 35.8 min of uptime a restart can
            # look like a wrap of the microsecond counter).
            self._last_n = None
            self._clock.restart()
            return
        if rows is None or self.info is None:
            return
        resets = self._clock.resets
        t_s = self._clock.seconds(parsed.t_us, 1e6 / self.info.rate_hz)
        if self._clock.resets != resets:
            # Its clock went back: the device restarted (hello lost), its counter too.
            self.stats.device_resets = self._clock.resets
            self._last_n = None
        if self._last_n is not None:
            self.stats.dropped += (parsed.n - self._last_n - 1) % COUNTER_MOD
        self._last_n = parsed.n
        lsb = self.info.lsb_m_s2
        full_scale = self.info.range_g * G_M_S2
        a = tuple(c * lsb for c in parsed.counts)
        if max(abs(v) for v in a) >= full_scale:
            self.stats.saturated += 1
        self.stats.samples += 1
        rows.append((t_s, a[0], a[1], a[2]))
