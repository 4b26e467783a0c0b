"""Loop pacing at a fixed rate, with timing statistics that survive Ctrl-C.

Each loop of the station owns one :class:`LoopTimer`. ``wait()`` sleeps until the next
tick's deadline (coarse sleep, then a short spin for the last fraction of a
millisecond, since ``time.sleep`` overshoots by 50-100 us on Linux) and records the
tick's lateness into a fixed histogram, so a loop running for hours allocates nothing
and the percentiles are always available.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

#: Lateness histogram: 10 us bins up to 100 ms; later ticks land in the last bin.
_BIN_S = 1e-5
_BINS = 10_000


@dataclass(frozen=True)
class LoopStats:
    """What a loop achieved: the figures of ``--stats``."""

    name: str
    target_hz: float
    rate_hz: float
    ticks: int
    on_time_pct: float
    jitter_ms: dict[str, float]
    #: Ticks skipped because the loop fell a whole period or more behind.
    skipped: int

    def as_dict(self) -> dict:
        d = asdict(self)
        d.pop("name")
        return d


class LoopTimer:
    """Paces a loop at ``rate_hz`` and measures how late each tick starts.

    A tick is *on time* when it starts no later than ``on_time_s`` after its deadline
    (half a period by default). A loop that falls a whole period behind skips the
    missed ticks rather than bursting to catch up.
    """

    def __init__(
        self,
        rate_hz: float,
        name: str = "loop",
        spin_s: float = 2e-4,
        on_time_s: float | None = None,
        clock=time.perf_counter,
    ):
        if rate_hz <= 0:
            raise ValueError(f"{name}: rate_hz must be positive, got {rate_hz}")
        self.name = name
        self.rate_hz = float(rate_hz)
        self.period_s = 1.0 / rate_hz
        self.spin_s = spin_s
        self.on_time_s = self.period_s / 2 if on_time_s is None else on_time_s
        self._clock = clock
        self._hist = np.zeros(_BINS, np.int64)
        self._on_time = 0
        self._ticks = 0
        self._skipped = 0
        self._start: float | None = None
        self._next = 0.0
        self._last = 0.0

    def start(self, at: float | None = None) -> float:
        """Set the schedule's origin (clock seconds; default now); returns it."""
        self._start = self._clock() if at is None else at
        self._next = self._start
        return self._start

    def wait(self) -> float:
        """Sleep until the next tick; returns the tick's scheduled time (clock seconds)."""
        if self._start is None:
            self.start()
        deadline = self._next
        now = self.wait_until(deadline)
        self._next = deadline + self.period_s
        if now - self._next >= self.period_s:
            missed = int((now - self._next) // self.period_s)
            self._skipped += missed
            self._next += missed * self.period_s
        return deadline

    def wait_until(self, deadline: float) -> float:
        """Sleep until ``deadline`` (clock seconds) and record how late we woke; returns now.

        For loops paced by their data's own time stamps (a replayed recording)."""
        if self._start is None:
            self.start()
        remaining = deadline - self._clock()
        if remaining > self.spin_s:
            time.sleep(remaining - self.spin_s)
        while self._clock() < deadline:
            pass
        now = self._clock()
        self._record(now - deadline)
        self._last = now
        return now

    def mark(self) -> float:
        """Count a tick that was not scheduled (a live camera's frame); returns now."""
        if self._start is None:
            self.start()
        self._last = self._clock()
        self._record(0.0)
        return self._last

    def stats_due(self, every_ticks: int | None = None) -> bool:
        """True once every ``every_ticks`` ticks (default: once a second)."""
        n = every_ticks or max(1, round(self.rate_hz))
        return self._ticks % n == 0 and self._ticks > 0

    def _record(self, late_s: float) -> None:
        self._ticks += 1
        if late_s <= self.on_time_s:
            self._on_time += 1
        b = int(late_s / _BIN_S)
        self._hist[min(max(b, 0), _BINS - 1)] += 1

    def _percentile_ms(self, q: float) -> float:
        if self._ticks == 0:
            return float("nan")
        cum = np.cumsum(self._hist)
        idx = int(np.searchsorted(cum, q / 100.0 * self._ticks))
        return (idx + 1) * _BIN_S * 1e3  # upper edge of the bin: never optimistic

    def stats(self) -> LoopStats:
        elapsed = (self._last - self._start) if self._start is not None else 0.0
        rate = (self._ticks - 1) / elapsed if self._ticks > 1 and elapsed > 0 else 0.0
        return LoopStats(
            name=self.name,
            target_hz=self.rate_hz,
            rate_hz=rate,
            ticks=self._ticks,
            on_time_pct=100.0 * self._on_time / self._ticks if self._ticks else 0.0,
            jitter_ms={"p50": self._percentile_ms(50), "p99": self._percentile_ms(99)},
            skipped=self._skipped,
        )


class LatencyHistogram:
    """p50/p99 of a latency measured many times (e.g. frame arrival to motor command)."""

    def __init__(self) -> None:
        self._hist = np.zeros(_BINS, np.int64)
        self.count = 0

    def add(self, latency_s: float) -> None:
        b = int(latency_s / _BIN_S)
        self._hist[min(max(b, 0), _BINS - 1)] += 1
        self.count += 1

    def percentiles_ms(self) -> dict[str, float]:
        if self.count == 0:
            return {"p50": float("nan"), "p99": float("nan")}
        cum = np.cumsum(self._hist)
        out = {}
        for q in (50, 99):
            idx = int(np.searchsorted(cum, q / 100.0 * self.count))
            out[f"p{q}"] = (idx + 1) * _BIN_S * 1e3
        return out
