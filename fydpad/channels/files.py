"""File channels: WAV (int16, stated full scale) and CSV (``t_s,<name>``), written block by
block so the file is valid if the process stops (the stdlib ``wave`` writer patches the
header after every write; the CSV is flushed per block)."""

from __future__ import annotations

import wave
from pathlib import Path
from types import TracebackType

import numpy as np
from numpy.typing import NDArray

from fydpad.channels.base import ChannelError, zero_nonfinite


class WavChannel:
    """Mono 16-bit PCM; ``full_scale`` maps to 32767; samples beyond it are clipped and counted."""

    def __init__(self, path: str | Path, rate_hz: float, name: str = "vibration",
                 full_scale: float = 1.0) -> None:
        self.name, self.rate_hz, self.full_scale = name, float(rate_hz), float(full_scale)
        self.n_clipped = 0
        #: NaN or infinite samples, written as 0.
        self.n_nonfinite = 0
        self.n_written = 0
        try:
            self._fh = open(path, "wb")
        except OSError as exc:
            raise ChannelError(f"{path}: cannot open for writing ({exc}); "
                               "check the folder") from exc
        self._w = wave.open(self._fh, "wb")
        self._w.setnchannels(1)
        self._w.setsampwidth(2)
        self._w.setframerate(round(rate_hz))
        self._closed = False

    def write(self, block: NDArray[np.float64]) -> None:
        x, bad = zero_nonfinite(block)  # NaN would become an arbitrary int16
        self.n_nonfinite += bad
        v = x / self.full_scale
        over = np.abs(v) > 1.0
        self.n_clipped += int(np.count_nonzero(over))
        pcm = np.round(np.clip(v, -1.0, 1.0) * 32767).astype("<i2")
        self._w.writeframes(pcm.tobytes())
        self._fh.flush()  # the header was patched by writeframes; make it visible now
        self.n_written += len(pcm)

    def close(self) -> None:
        if not self._closed:
            self._w.close()
            self._fh.close()
            self._closed = True

    def __enter__(self) -> WavChannel:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class CsvChannel:
    """CSV with header ``t_s,<name>``; t_s = sample index / rate_hz."""

    def __init__(self, path: str | Path, rate_hz: float, name: str = "vibration") -> None:
        self.name, self.rate_hz = name, float(rate_hz)
        self.n_written = 0
        try:
            self._f = open(path, "w", newline="")
        except OSError as exc:
            raise ChannelError(f"{path}: cannot open for writing ({exc}); "
                               "check the folder") from exc
        self._f.write(f"t_s,{name}\n")
        self._f.flush()

    def write(self, block: NDArray[np.float64]) -> None:
        v = np.asarray(block, dtype=np.float64)
        t = (self.n_written + np.arange(len(v))) / self.rate_hz
        self._f.write("".join(f"{a:.6f},{b:.9g}\n" for a, b in zip(t, v, strict=True)))
        self._f.flush()
        self.n_written += len(v)

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()

    def __enter__(self) -> CsvChannel:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
