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

from collections.abc import Callable, Sequence

from vision.sensors import data_line, hello_line
from vision.serial_line import PtyEmulator


def _default_sample(k: int) -> tuple[Sequence[int], int | None]:
    # A rest pose: 1.31 V (about 100 mm) on every sensor, no load.
    return (268, 268, 268), 0


class BoardEmulator(PtyEmulator):
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
        super().__init__(rate_hz, hello_on_start)
        self.sample_fn = sample_fn
        #: A deadman pedal: True pressed, False released (both sent in every data line's
        #: 7th field), None: the board has none (6 fields). Set it any time.
        self.pedal: bool | None = None
        self.adc_bits = adc_bits
        self.vref_mv = vref_mv
        self.start_ms = start_ms

    def _hello(self) -> bytes:
        return hello_line(self.rate_hz, self.adc_bits, self.vref_mv)

    def _line(self, k: int) -> bytes:
        v_raw, force_raw = self.sample_fn(k)
        t_ms = self.start_ms + round(k * 1000.0 / self.rate_hz)
        return data_line(t_ms, v_raw, force_raw, self.pedal)

