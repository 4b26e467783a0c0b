"""Bounded buffers between the 1 kHz render loop and whatever consumes its output at its
own pace: a sound card's callback, a file writer's thread.

:class:`SampleRing` is a single-producer single-consumer ring of samples (float32 for a
sound card, float64 for a file); :class:`RowRing` one of fixed-width rows (a log). The
writer only advances ``_w`` and the reader only ``_r``, each after its copy, so neither
waits for the other (CPython's GIL makes each index update atomic and ordered; no lock
that the 1 kHz loop could block on).

:class:`RingFeed` puts the rest of an audio channel around it, free of I/O: the writer's
end zeroes NaN and infinite samples (counted), scales, resamples
(:class:`fydpad.channels.resample.Resampler`, state carried across blocks), clips and
pushes; a full ring drops the samples that do not fit and counts them.
The reader's end (the card's callback) plays what is there; when the ring runs dry it
outputs zeros, counts an underrun and waits until ``prefill_frames`` are buffered again
before it plays on (so one late block costs one gap, not a gap per callback).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fydpad.channels.base import zero_nonfinite
from fydpad.channels.resample import Resampler


class SampleRing:
    """Bounded SPSC ring of samples: ``push`` drops what does not fit, ``pop_into``
    zero-fills what is missing; both return how many samples moved."""

    def __init__(self, capacity: int, dtype: type = np.float32) -> None:
        if capacity <= 0:
            raise ValueError(f"ring capacity must be positive, not {capacity}")
        self.capacity = int(capacity)
        self._buf = np.zeros(self.capacity, dtype)
        self._w = 0  # samples ever pushed (writer's)
        self._r = 0  # samples ever popped (reader's)

    @property
    def level(self) -> int:
        """Samples buffered now."""
        return self._w - self._r

    @property
    def free(self) -> int:
        return self.capacity - (self._w - self._r)

    def push(self, x: NDArray[np.floating]) -> int:
        n = min(len(x), self.capacity - (self._w - self._r))
        i = self._w % self.capacity
        first = min(n, self.capacity - i)
        self._buf[i:i + first] = x[:first]
        self._buf[:n - first] = x[first:n]
        self._w += n  # publish after the copy
        return n

    def pop_into(self, out: NDArray[np.float32]) -> int:
        n = min(len(out), self._w - self._r)
        i = self._r % self.capacity
        first = min(n, self.capacity - i)
        out[:first] = self._buf[i:i + first]
        out[first:n] = self._buf[:n - first]
        out[n:] = 0.0
        self._r += n  # free the space after the copy
        return n


class RowRing:
    """Bounded SPSC ring of float64 rows of ``width`` values, preallocated.

    The writer's ``push`` stores one row in place (no allocation) or, when the ring is
    full, drops it and counts it in ``n_dropped``: it never waits. The reader's
    ``pop_into`` copies up to ``len(out)`` rows out. ``peak_level`` is the fullest the
    ring has been (the margin left against a disk stall)."""

    def __init__(self, width: int, capacity: int) -> None:
        if width <= 0 or capacity <= 0:
            raise ValueError(f"ring of {capacity} rows of {width} must be positive")
        self.width, self.capacity = int(width), int(capacity)
        self._buf = np.zeros((self.capacity, self.width), np.float64)
        self._flat = self._buf.reshape(-1)
        self._w = 0  # rows ever pushed (writer's)
        self._r = 0  # rows ever popped (reader's)
        self.n_pushed = 0
        self.n_dropped = 0
        self.peak_level = 0

    @property
    def level(self) -> int:
        return self._w - self._r

    def push(self, *values: float) -> bool:
        """Store one row (``width`` values); False (counted) when the ring is full."""
        w = self._w
        level = w - self._r
        if level >= self.capacity:
            self.n_dropped += 1
            return False
        flat = self._flat
        k = (w % self.capacity) * self.width
        for v in values:
            flat[k] = v
            k += 1
        self._w = w + 1  # publish after the copy
        self.n_pushed += 1
        if level >= self.peak_level:
            self.peak_level = level + 1
        return True

    def pop_into(self, out: np.ndarray) -> int:
        """Copy up to ``len(out)`` rows into ``out`` (shape (n, width)); how many."""
        n = min(len(out), self._w - self._r)
        i = self._r % self.capacity
        first = min(n, self.capacity - i)
        out[:first] = self._buf[i:i + first]
        out[first:n] = self._buf[:n - first]
        self._r += n  # free the space after the copy
        return n


class RingFeed:
    """Writer (``write``, the render loop) and reader (``fill``, the card's callback) ends
    of an audio channel. Counters are in output frames except ``n_written`` (input
    samples); each is written by one end only."""

    def __init__(self, rate_in_hz: float, rate_out_hz: float, capacity_frames: int,
                 prefill_frames: int, full_scale: float = 1.0) -> None:
        if not 0 < prefill_frames <= capacity_frames:
            raise ValueError(f"prefill {prefill_frames} must be in 1..{capacity_frames} frames")
        if not full_scale > 0:
            raise ValueError(f"full_scale must be positive, not {full_scale}")
        self.rate_in_hz, self.rate_out_hz = float(rate_in_hz), float(rate_out_hz)
        self.resampler = (None if self.rate_in_hz == self.rate_out_hz
                          else Resampler(self.rate_in_hz, self.rate_out_hz))
        self.ring = SampleRing(capacity_frames)
        self.prefill_frames = int(prefill_frames)
        self.full_scale = float(full_scale)
        #: Set by the closer: play out what is buffered, do not wait for a prefill.
        self.draining = False
        # writer's counters
        self.n_written = 0
        #: Input samples that were NaN or infinite, played as 0.
        self.n_nonfinite = 0
        self.n_clipped = 0
        self.n_dropped = 0
        # reader's counters
        self.n_played = 0
        self.n_underruns = 0
        self.n_underrun_frames = 0
        self._playing = False
        self._started = False

    def write(self, block: NDArray[np.floating]) -> None:
        """Zero what is not finite, scale, resample, clip at full scale, push; never blocks
        (a full ring drops)."""
        # Before the resampler: a NaN in its state would poison every later block.
        x, bad = zero_nonfinite(block)
        self.n_written += len(x)
        self.n_nonfinite += bad
        y = x if self.resampler is None else self.resampler.process(x)
        y = y / self.full_scale
        over = np.abs(y) > 1.0
        if over.any():
            self.n_clipped += int(np.count_nonzero(over))
            y = np.clip(y, -1.0, 1.0)
        self.n_dropped += len(y) - self.ring.push(y)

    def fill(self, out: NDArray[np.float32]) -> int:
        """Fill one callback buffer; returns the frames that came from the ring."""
        level = self.ring.level
        if not self._playing:
            if level >= self.prefill_frames or (self.draining and level > 0):
                self._playing = self._started = True
            else:
                out[:] = 0.0
                if self._started and not self.draining:
                    self.n_underrun_frames += len(out)  # still waiting after an underrun
                return 0
        n = self.ring.pop_into(out)
        self.n_played += n
        if n < len(out):
            self._playing = False
            if not self.draining:
                self.n_underruns += 1
                self.n_underrun_frames += len(out) - n
        return n
