"""Loop pacing statistics, on a virtual clock (no timing of the machine itself)."""

from __future__ import annotations

import pytest

from fydpad.pacing import LatencyHistogram, LoopTimer


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0
        self.lateness: list[float] = []

    def __call__(self) -> float:
        return self.t


def test_stats_from_known_lateness(monkeypatch):
    clock = FakeClock()
    # time.sleep advances the virtual clock to the deadline, plus a planned lateness.
    plan = iter([0.0] * 5 + [0.0001] * 90 + [0.0003] * 4 + [0.0025])

    def fake_sleep(s: float) -> None:
        clock.t += s + 2e-4 + next(plan)  # the timer sleeps to deadline - spin

    monkeypatch.setattr("fydpad.pacing.time.sleep", fake_sleep)
    timer = LoopTimer(1000.0, "render", clock=clock)
    timer.start()
    clock.t += 1e-6  # the first deadline is now: make every tick sleep
    timer._next += 1e-3
    for _ in range(100):
        timer.wait()
    s = timer.stats()
    assert s.ticks == 100
    # 99 ticks late by <= 0.3 ms are on time (half a period = 0.5 ms), the 2.5 ms one is not.
    assert s.on_time_pct == pytest.approx(99.0)
    assert s.jitter_ms["p50"] == pytest.approx(0.11, abs=0.011)
    assert s.jitter_ms["p99"] == pytest.approx(0.31, abs=0.011)
    assert s.skipped == 1  # 2.5 ms late: a whole period behind, one tick skipped


def test_rate_is_measured():
    clock = FakeClock()
    timer = LoopTimer(10.0, "vision", clock=clock)
    timer.start()
    for _ in range(11):
        clock.t = timer._next  # wake exactly at the deadline
        timer.wait()
    assert timer.stats().rate_hz == pytest.approx(10.0)


def test_latency_histogram():
    h = LatencyHistogram()
    for ms in range(1, 101):
        h.add(ms / 1000)
    p = h.percentiles_ms()
    assert p["p50"] == pytest.approx(50.0, abs=0.02)
    assert p["p99"] == pytest.approx(99.0, abs=0.02)


def test_bad_rate():
    with pytest.raises(ValueError, match="render"):
        LoopTimer(0, "render")
