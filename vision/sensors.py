"""IR distance sensors and load cell behind two small Protocols, with backends: the
serial sensor board (pyserial; docs/sensor_board_protocol.md), replay from a
recording's ``ir.csv``/``force.csv``, and (elsewhere) the synthetic pad.

``read()`` returns the next sample in time order, blocking until it arrives; it
returns None when the source has ended (a replay or a simulation ran out) and raises
``SensorError`` naming the device when a live device is missing, unplugged or silent
for longer than its timeout. A live source never hangs and never crashes on bad bytes:
malformed lines are counted in ``stats`` and skipped.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from vision.config import ForceConfig, IRConfig
from vision.errors import DeviceFault
from vision.force import raw_to_force, saturation_flags
from vision.recording import PadRecording
from vision.serial_line import MAX_LINE_BYTES as MAX_LINE_BYTES
from vision.serial_line import ChecksumError as ChecksumError
from vision.serial_line import DeviceClock, LineError, frame_line, take_line, unframe_line
from vision.serial_line import checksum as checksum
from vision.serial_line import parse_serial_spec as parse_serial_spec


class SensorError(DeviceFault, RuntimeError):
    """A sensor device is missing, disconnected or silent; the message names it."""

    device = "sensor board"
    check = "its cable, its power and the [sensors] port in the configuration"


@dataclass(frozen=True, slots=True)
class IRSample:
    """The three IR sensors' voltages at ``t_s``; ``valid[i]`` is False where volts[i]
    is outside the sensor's valid range (the indentation then is not computed)."""

    t_s: float
    volts: tuple[float, float, float]
    valid: tuple[bool, bool, bool]


@dataclass(frozen=True, slots=True)
class ForceSample:
    """Load cell force at ``t_s`` in N; ``raw`` the ADC counts when known."""

    t_s: float
    force_n: float
    saturated: bool
    raw: float | None = None


@runtime_checkable
class IRSource(Protocol):
    """Anything giving the IR triple: serial board, replay, synthetic pad."""

    def read(self) -> IRSample | None:
        """The next sample (blocking); None when the source has ended."""
        ...

    def close(self) -> None: ...


@runtime_checkable
class ForceSource(Protocol):
    """Anything giving the load cell force: serial board, replay, synthetic pad."""

    def read(self) -> ForceSample | None:
        """The next sample (blocking); None when the source has ended."""
        ...

    def close(self) -> None: ...


def ir_valid_flags(
    volts: Sequence[float], valid_range_v: Sequence[tuple[float, float]],
) -> tuple[bool, bool, bool]:
    """Per sensor: inside its valid range (eq. (1) is not extrapolated); NaN is invalid."""
    return tuple(bool(lo <= v <= hi) for v, (lo, hi) in zip(volts, valid_range_v,
                                                            strict=True))  # type: ignore[return-value]


# --------------------------------------------------------------------------- replay


class ReplayIR:
    """IR samples from arrays or a recording's ``ir.csv``, in order, as fast as read."""

    def __init__(self, t_s: ArrayLike, volts: ArrayLike, config: IRConfig | None = None):
        self._t = np.asarray(t_s, np.float64)
        self._v = np.asarray(volts, np.float64).reshape(-1, 3)
        self._ranges = (config or IRConfig()).valid_range_v
        self._k = 0

    @classmethod
    def from_recording(cls, recording: PadRecording, config: IRConfig | None = None) -> ReplayIR:
        data = recording.read_ir()
        if data is None:
            raise SensorError(f"{recording.path / 'ir.csv'}: missing (no IR sensor data)")
        return cls(data[0], data[1], config)

    def read(self) -> IRSample | None:
        if self._k >= self._t.size:
            return None
        v = tuple(float(x) for x in self._v[self._k])
        s = IRSample(float(self._t[self._k]), v, ir_valid_flags(v, self._ranges))  # type: ignore[arg-type]
        self._k += 1
        return s

    def close(self) -> None:
        self._k = self._t.size


class ReplayForce:
    """Force samples from arrays or a recording's ``force.csv`` (already in N)."""

    def __init__(self, t_s: ArrayLike, force_n: ArrayLike, config: ForceConfig | None = None):
        self._t = np.asarray(t_s, np.float64)
        self._f = np.asarray(force_n, np.float64)
        self._sat = saturation_flags(self._f, None, config)
        self._k = 0

    @classmethod
    def from_recording(cls, recording: PadRecording,
                       config: ForceConfig | None = None) -> ReplayForce:
        data = recording.read_force()
        if data is None:
            raise SensorError(f"{recording.path / 'force.csv'}: missing (no load cell data)")
        return cls(data[0], data[1], config)

    def read(self) -> ForceSample | None:
        if self._k >= self._t.size:
            return None
        k = self._k
        self._k += 1
        return ForceSample(float(self._t[k]), float(self._f[k]), bool(self._sat[k]))

    def close(self) -> None:
        self._k = self._t.size


# --------------------------------------------------------------------------- board protocol

PROTOCOL_VERSION = 1
BOARD_NAME = "FYDPAD-BOARD"
def data_line(t_ms: int, v_raw: Sequence[int], force_raw: int | None,
              pedal: bool | None = None) -> bytes:
    """A data line; ``pedal`` (the deadman pedal: True pressed) adds the optional 7th
    field, None leaves it out (a board without one)."""
    f = "" if force_raw is None else str(int(force_raw))
    tail = "" if pedal is None else f",{int(bool(pedal))}"
    return frame_line(f"D,{int(t_ms) % 2**32},{int(v_raw[0])},{int(v_raw[1])},"
                      f"{int(v_raw[2])},{f}{tail}")


def hello_line(rate_hz: float, adc_bits: int, vref_mv: int) -> bytes:
    return frame_line(f"H,{BOARD_NAME},{PROTOCOL_VERSION},{rate_hz:g},{adc_bits},{vref_mv}")


@dataclass(frozen=True)
class BoardInfo:
    """From the board's hello line."""

    name: str
    version: int
    rate_hz: float
    adc_bits: int
    vref_v: float


@dataclass(frozen=True)
class DataLine:
    t_ms: int
    v_raw: tuple[int, int, int]
    force_raw: int | None
    #: The deadman pedal: True pressed, False released, None no pedal (no 7th field).
    pedal: bool | None = None


def parse_line(line: bytes, adc_bits: int = 10) -> DataLine | BoardInfo:
    """One line (without the newline) -> DataLine or BoardInfo, or LineError."""
    fields = unframe_line(line)
    try:
        if fields[0] == "D" and len(fields) in (6, 7):
            v = (int(fields[2]), int(fields[3]), int(fields[4]))
            if not all(0 <= x < 2**adc_bits for x in v):
                raise LineError(f"ADC value out of 0..{2**adc_bits - 1}")
            force = None if fields[5] == "" else int(fields[5])
            pedal = None
            if len(fields) == 7 and fields[6] != "":
                if fields[6] not in ("0", "1"):
                    raise LineError(f"pedal field {fields[6][:8]!r} is not 0 or 1")
                pedal = fields[6] == "1"
            return DataLine(int(fields[1]), v, force, pedal)  # type: ignore[arg-type]
        if fields[0] == "H" and len(fields) == 6:
            return BoardInfo(fields[1], int(fields[2]), float(fields[3]), int(fields[4]),
                             int(fields[5]) / 1000.0)
    except LineError:
        raise
    except ValueError:
        raise LineError("a field is not a number") from None
    raise LineError(f"unknown line type or field count ({fields[0][:8]!r}, {len(fields)})")


@dataclass
class BoardStats:
    """What the reader saw: good data lines, and bad ones counted and skipped."""

    lines_ok: int = 0
    hello: int = 0
    bad_checksum: int = 0
    malformed: int = 0
    overlong: int = 0
    board_resets: int = 0
    last_error: str = ""


@dataclass
class _Queues:
    ir: collections.deque[IRSample] = field(default_factory=lambda: collections.deque(maxlen=1024))
    force: collections.deque[ForceSample] = field(
        default_factory=lambda: collections.deque(maxlen=1024))


class SerialBoard:
    """The microcontroller ADC board on a serial port (docs/sensor_board_protocol.md).

    One line carries both IR and force, so the board is one reader with two views,
    ``board.ir`` (an IRSource) and ``board.force`` (a ForceSource); each view returns
    its samples in order, reading the port when it has none queued. Thread-safe: the
    IR and force loops may each read their view.
    """

    def __init__(
        self, port: str, baud: int = 115200, ir_config: IRConfig | None = None,
        force_config: ForceConfig | None = None, timeout_s: float = 1.0,
        serial_factory: Callable[..., Any] | None = None,
    ):
        import serial  # pyserial; imported here so replay works without it

        self.port = port
        self.timeout_s = float(timeout_s)
        self.ir_config = ir_config or IRConfig()
        self.force_config = force_config or ForceConfig()
        self.adc_bits = self.ir_config.adc_bits
        self.vref_v = self.ir_config.adc_vref_v
        self.info: BoardInfo | None = None
        #: The deadman pedal as of the newest data line (None: the board has none).
        self.pedal: bool | None = None
        self.stats = BoardStats()
        self._serial_errors: tuple[type[BaseException], ...] = (serial.SerialException, OSError)
        self._clock = DeviceClock(1000.0)
        self._buf = bytearray()
        self._queues = _Queues()
        self._lock = threading.Lock()
        factory = serial_factory or serial.Serial
        try:
            self._ser = factory(port, baud, timeout=0.05, write_timeout=0.5)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise SensorError(f"{port}: cannot open the sensor board ({exc})") from None
        try:
            self._ser.reset_input_buffer()  # stale bytes from before we opened
            self._ser.write(b"?\n")  # ask for the hello line (adc bits, vref, rate)
        except self._serial_errors as exc:
            self._ser.close()
            raise SensorError(f"{port}: sensor board not responding ({exc})") from None
        self.ir: IRSource = _View(self, "ir")
        self.force: ForceSource = _View(self, "force")

    # The views call this with the lock held.
    def _next(self, kind: str) -> IRSample | ForceSample:
        q: collections.deque[Any] = getattr(self._queues, kind)
        deadline = time.monotonic() + self.timeout_s
        while not q:
            if time.monotonic() > deadline:
                # Data lines arrive, but none with this kind (an empty force field).
                raise SensorError(f"{self.port}: the sensor board sends no {kind} data "
                                  f"(for {self.timeout_s:g} s; load cell not connected?)")
            self._read_one_data_line()
        return q.popleft()

    def _read_one_data_line(self) -> None:
        deadline = time.monotonic() + self.timeout_s
        while True:
            line, overlong = take_line(self._buf)
            self.stats.overlong += overlong
            if line is not None:
                if self._handle(line):
                    return
                continue
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                bad = self.stats.bad_checksum + self.stats.malformed + self.stats.overlong
                raise SensorError(
                    f"{self.port}: no valid data from the sensor board for {self.timeout_s:g} s "
                    f"({bad} bad lines so far; is it powered and sending?)")
            try:
                # The port's own timeout (50 ms, set at open) bounds this wait; changing
                # it here would reconfigure the port on every read.
                chunk = self._ser.read(max(1, min(self._ser.in_waiting, 4096)))
            except self._serial_errors as exc:
                raise SensorError(f"{self.port}: sensor board disconnected ({exc})") from None
            self._buf += chunk

    def _handle(self, line: bytes) -> bool:
        """Parse one line; queue its samples. True for a data line."""
        if not line.strip():
            return False
        try:
            parsed = parse_line(line, self.adc_bits)
        except ChecksumError as exc:
            self.stats.bad_checksum += 1
            self.stats.last_error = str(exc)
            return False
        except LineError as exc:
            self.stats.malformed += 1
            self.stats.last_error = f"{exc}: {line[:40]!r}"
            return False
        if line.rfind(b"$") > 0:
            # A line cut short and run into this one: its fragment is lost, count it.
            self.stats.malformed += 1
        if isinstance(parsed, BoardInfo):
            self.info = parsed
            self.adc_bits, self.vref_v = parsed.adc_bits, parsed.vref_v
            self.stats.hello += 1
            return False
        self.stats.lines_ok += 1
        self.pedal = parsed.pedal
        t_s = self._clock.seconds(parsed.t_ms, 1000.0 / self.ir_config.rate_hz)
        self.stats.board_resets = self._clock.resets
        scale = self.vref_v / 2**self.adc_bits  # Arduino convention: V = raw * Vref / 2^bits
        volts = tuple(r * scale for r in parsed.v_raw)
        valid = ir_valid_flags(volts, self.ir_config.valid_range_v)
        self._queues.ir.append(IRSample(t_s, volts, valid))  # type: ignore[arg-type]
        if parsed.force_raw is not None:
            fr = raw_to_force(parsed.force_raw, self.force_config)
            self._queues.force.append(ForceSample(t_s, float(fr.force_n), bool(fr.saturated),
                                                  float(parsed.force_raw)))
        return True

    def read(self) -> tuple[IRSample, ForceSample | None]:
        """For one sensor loop reading both: the next IR sample and the force from the
        same line (None when that line had none). Do not mix with the views' reads."""
        with self._lock:
            ir = self._next("ir")
            f = self._queues.force
            while f and f[0].t_s < ir.t_s:
                f.popleft()
            force = f.popleft() if f and f[0].t_s == ir.t_s else None
            return ir, force  # type: ignore[return-value]

    def flush_input(self) -> None:
        """Drop what has arrived and not been read (lines from before a loop started)."""
        with self._lock:
            try:
                self._ser.reset_input_buffer()
            except self._serial_errors as exc:
                raise SensorError(f"{self.port}: sensor board disconnected ({exc})") from None
            self._buf.clear()
            self._queues.ir.clear()
            self._queues.force.clear()

    def close(self) -> None:
        try:
            self._ser.close()
        except self._serial_errors:
            pass

    def __enter__(self) -> SerialBoard:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _View:
    """One kind of sample (IR or force) from a SerialBoard."""

    def __init__(self, board: SerialBoard, kind: str):
        self._board = board
        self._kind = kind

    def read(self) -> Any:
        with self._board._lock:
            return self._board._next(self._kind)

    def close(self) -> None:
        self._board.close()
