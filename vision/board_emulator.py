"""An emulated sensor board speaking docs/sensor_board_protocol.md on a pseudo-terminal,
so the real pyserial reader (``vision.sensors.SerialBoard``) can be tested end to end,
and a station can run without the hardware.

The board streams data lines at its rate from a thread, answers ``?`` with its hello
line, and can be made to misbehave as real boards and cables do: raw bytes injected
(garbage, partial lines, bad checksums), silence (``pause``), and unplugging (the pty
master closed). Like a UART without flow control, bytes the reader does not take in
time are dropped rather than blocking the board.
"""

from __future__ import annotations

import errno
import os
import select
import threading
import time
import tty
from collections.abc import Callable, Sequence

from vision.sensors import data_line, hello_line


def _default_sample(k: int) -> tuple[Sequence[int], int | None]:
    # A rest pose: 1.31 V (about 100 mm) on every sensor, no load.
    return (268, 268, 268), 0


class BoardEmulator:
    """The ADC board on the master side of a pty; ``port`` is the path to open.

    ``sample_fn(k)`` gives sample k's raw IR counts and force counts (None: no load
    cell). Time on the board is ``start_ms + k * 1000 / rate_hz`` milliseconds.
    """

    def __init__(
        self,
        sample_fn: Callable[[int], tuple[Sequence[int], int | None]] = _default_sample,
        rate_hz: float = 100.0,
        adc_bits: int = 10,
        vref_mv: int = 5000,
        start_ms: int = 0,
        hello_on_start: bool = True,
    ):
        self.sample_fn = sample_fn
        self.rate_hz = float(rate_hz)
        self.adc_bits = adc_bits
        self.vref_mv = vref_mv
        self.start_ms = start_ms
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

    def start(self, streaming: bool = True) -> BoardEmulator:
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

    def __enter__(self) -> BoardEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ internals

    def _hello(self) -> bytes:
        return hello_line(self.rate_hz, self.adc_bits, self.vref_mv)

    def _line(self, k: int) -> bytes:
        v_raw, force_raw = self.sample_fn(k)
        t_ms = self.start_ms + round(k * 1000.0 / self.rate_hz)
        return data_line(t_ms, v_raw, force_raw)

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
