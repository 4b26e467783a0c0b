"""The serial line transport every board of the project speaks: ASCII lines
``$payload*HH\n`` with an XOR checksum (as NMEA 0183), cut and resynchronised on a byte
stream, a 32-bit device clock unwrapped into seconds, the ``serial:PORT[@BAUD]`` spec, and
:class:`PtyEmulator`, the pseudo-terminal base of the boards' emulators.

Used by the sensor board (:mod:`vision.sensors`, docs/sensor_board_protocol.md) and the
fabric accelerometer (:mod:`fydpad.accel.serial`, docs/accel_protocol.md).
"""

from __future__ import annotations

import errno
import os
import select
import threading
import time
import tty

from vision.errors import DeviceFault

#: Longest line the board sends is about 50 bytes; beyond this it is garbage.
MAX_LINE_BYTES = 128


def checksum(payload: bytes) -> int:
    """XOR of the bytes between '$' and '*' (as NMEA 0183), two hex digits on the wire."""
    c = 0
    for b in payload:
        c ^= b
    return c


def frame_line(payload: str) -> bytes:
    """``$payload*HH\\n`` for a payload such as ``D,1234,512,498,530,-1022``."""
    body = payload.encode("ascii")
    return b"$" + body + b"*" + f"{checksum(body):02X}".encode("ascii") + b"\n"


class LineError(DeviceFault, ValueError):
    """A line that is not a valid board line; the message says why."""

    device = "serial line"
    check = "the baud rate and that the board speaks this protocol version"


class ChecksumError(LineError):
    """The checksum does not match (a corrupted line)."""


def unframe_line(line: bytes) -> list[str]:
    """``$payload*HH`` (without the newline) -> the payload's comma-separated fields, or
    LineError / ChecksumError. The last ``$`` starts the line (resync after a cut line)."""
    line = line.rstrip(b"\r")
    start = line.rfind(b"$")  # a line cut short and followed by a good one: resync
    if start < 0:
        raise LineError("no '$'")
    line = line[start:]
    star = line.rfind(b"*")
    if star < 0 or len(line) != star + 3:
        raise LineError("no '*HH' checksum at the end")
    body = line[1:star]
    try:
        expected = int(line[star + 1:], 16)
    except ValueError:
        raise LineError("checksum is not two hex digits") from None
    if checksum(body) != expected:
        raise ChecksumError("checksum mismatch")
    try:
        return body.decode("ascii").split(",")
    except UnicodeDecodeError:
        raise LineError("non-ASCII bytes") from None


def take_line(buf: bytearray, max_bytes: int = MAX_LINE_BYTES) -> tuple[bytes | None, bool]:
    """Pop the next complete line (without its newline) off ``buf``: (line, False). None
    when no line is complete; then, if ``buf`` holds more than ``max_bytes`` with no
    newline, it is dropped up to its last ``$`` (a line may be starting) and the second
    value is True (an overlong run, to be counted)."""
    nl = buf.find(b"\n")
    if nl >= 0:
        line = bytes(buf[:nl])
        del buf[:nl + 1]
        return line, False
    if len(buf) > max_bytes:
        start = buf.rfind(b"$")
        del buf[:start if start > 0 else len(buf)]
        return None, True
    return None, False


class DeviceClock:
    """A device's 32-bit tick counter -> seconds from the first sample: unwraps the
    counter and keeps time going forward across a device reset (its counter restarts).
    ``ticks_per_s`` is 1000 for the sensor board's milliseconds, 1e6 for microseconds.

    A count that goes back is a wrap only when it is a plausible one: the step forward
    across 2^32 is at most ``max_gap_s`` (a few dropped samples, never minutes). Any
    other step back is a restart, as is the next sample after ``restart()`` (the reader
    saw the device's hello line mid-stream): time then goes on one period after the last
    sample, whatever the new count."""

    def __init__(self, ticks_per_s: float = 1000.0, max_gap_s: float = 1.0) -> None:
        self.ticks_per_s = float(ticks_per_s)
        self.max_gap_s = float(max_gap_s)
        self._last: int | None = None
        self._offset = 0
        self._t0: int | None = None
        self._restarted = False
        self.resets = 0

    def restart(self) -> None:
        """The device restarted (its hello line): its next count starts a new epoch."""
        self._restarted = self._last is not None

    def seconds(self, ticks: int, period_ticks: float) -> float:
        last = self._last
        if last is not None and (self._restarted or ticks < last):
            step = ticks + 2**32 - last  # forward across a wrap of the counter
            if not self._restarted and step <= max(self.max_gap_s * self.ticks_per_s,
                                                   2 * period_ticks):
                self._offset += 2**32  # the counter wrapped (ms: 49.7 days; us: 71.6 min)
            else:
                # The device restarted its counter: continue one period after the last.
                self._offset += last - ticks + round(period_ticks)
                self.resets += 1
            self._restarted = False
        self._last = ticks
        t = ticks + self._offset
        if self._t0 is None:
            self._t0 = t
        return (t - self._t0) / self.ticks_per_s


def parse_serial_spec(spec: str, default_baud: int = 115200,
                      what: str = "sensor board") -> tuple[str, int]:
    """``serial:PORT[@BAUD]`` -> (port, baud); ValueError naming ``what`` and the problem."""
    kind, sep, rest = spec.partition(":")
    if kind != "serial" or not sep or not rest:
        raise ValueError(f"{what} {spec!r}: expected serial:PORT[@BAUD], "
                         f"e.g. serial:/dev/ttyACM0@{default_baud}")
    port, at, baud = rest.rpartition("@") if "@" in rest else (rest, "", "")
    if at:
        if not baud.isdigit() or int(baud) <= 0:
            raise ValueError(f"{what} {spec!r}: baud {baud!r} is not a positive integer")
        return port, int(baud)
    return port, default_baud


class PtyEmulator:
    """A device on the master side of a pseudo-terminal; ``port`` is the path to open.

    A thread streams one line per sample at ``rate_hz`` (``_line(k)``) while streaming,
    answers ``?`` with the device's hello line (``_hello()``), and the device can be made
    to misbehave as real boards and cables do: raw bytes injected (``send``), silence
    (``pause``), unplugging (the pty master closed). Like a UART without flow control,
    bytes the reader does not take in time are dropped rather than blocking the device.
    Subclasses give ``_hello`` and ``_line``.
    """

    def __init__(self, rate_hz: float = 100.0, hello_on_start: bool = True):
        self.rate_hz = float(rate_hz)
        self.hello_on_start = hello_on_start
        self._master, self._slave = os.openpty()
        # Raw mode: no echo, no line editing, bytes pass untouched (the reader sets the
        # same when it opens the port, but data may arrive before that).
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self.k = 0
        self.dropped_bytes = 0
        self.commands: list[bytes] = []
        self._streaming = threading.Event()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._unplugged = False

    # ------------------------------------------------------------------ control

    def start(self, streaming: bool = True) -> PtyEmulator:
        if streaming:
            self._streaming.set()
        self._thread = threading.Thread(target=self._run, name="board-emulator", daemon=True)
        self._thread.start()
        if self.hello_on_start:
            self.send(self._hello())
        return self

    def pause(self) -> None:
        """Stop sending data lines (the board hangs, the cable stays)."""
        self._streaming.clear()

    def resume(self) -> None:
        self._streaming.set()

    def send(self, data: bytes) -> None:
        """Write raw bytes now (garbage, partial lines, crafted lines)."""
        with self._lock:
            self._write(data)

    def send_sample(self, k: int | None = None) -> None:
        """Write one data line now (sample ``k``, default the next one)."""
        with self._lock:
            self._write(self._line(self.k if k is None else k))
            if k is None:
                self.k += 1

    def unplug(self) -> None:
        """The USB cable pulled: the pty master goes away."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        with self._lock:
            if not self._unplugged:
                self._unplugged = True
                os.close(self._master)

    def stop(self) -> None:
        self.unplug()
        try:
            os.close(self._slave)
        except OSError:
            pass

    def __enter__(self) -> PtyEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ internals

    def _write(self, data: bytes) -> None:
        if self._unplugged:
            return
        try:
            n = os.write(self._master, data)
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EIO):
                raise
            n = 0
        self.dropped_bytes += len(data) - n

    def _run(self) -> None:
        period_s = 1.0 / self.rate_hz
        next_t = time.monotonic()
        while not self._stop.is_set():
            timeout = max(0.0, next_t - time.monotonic())
            try:
                readable, _, _ = select.select([self._master], [], [], min(timeout, 0.05))
            except (OSError, ValueError):
                return  # closed under us
            if readable:
                self._serve_commands()
            now = time.monotonic()
            if now >= next_t:
                if self._streaming.is_set():
                    self.send_sample()
                # Catch up without a burst if the thread was starved (shared CI machine).
                next_t = max(next_t + period_s, now - period_s)

    def _serve_commands(self) -> None:
        try:
            data = os.read(self._master, 256)
        except OSError:
            return  # EIO: nobody has the port open at the moment
        for cmd in data.split(b"\n"):
            cmd = cmd.strip()
            if not cmd:
                continue
            self.commands.append(cmd)
            self._on_command(cmd)

    def _on_command(self, cmd: bytes) -> None:
        """Answer one host command (``?``: the hello line); others are ignored."""
        if cmd == b"?":
            self.send(self._hello())

    def _hello(self) -> bytes:
        raise NotImplementedError

    def _line(self, k: int) -> bytes:
        raise NotImplementedError
