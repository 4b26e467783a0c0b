"""Per-tick cost of the live chain inverse (128-tap minimum-phase FIR) in the 1 kHz
loop, against two per-sample baselines in the same run: scipy.signal.lfilter with its
zi carried, and np.convolve over a shifted history. Also the block path, per sample.

    nice python benchmarks/bench_compensation.py
"""

from __future__ import annotations

import time

import numpy as np
from scipy.signal import lfilter

from fydpad.chain.inverse_filter import InverseFilter, fir_filter
from fydpad.chain.live import NTAPS


def _per_tick_us(fn, x, reps: int = 3) -> float:
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        for v in x:
            fn(v)
        best = min(best, time.perf_counter() - t0)
    return best / len(x) * 1e6


def main() -> None:
    rng = np.random.default_rng(0)
    taps = rng.normal(size=NTAPS) * np.exp(-np.arange(NTAPS) / 20)
    x = [float(v) for v in rng.normal(size=20_000)]  # 20 s at 1 kHz

    live = InverseFilter(taps)
    t_live = _per_tick_us(live.tick, x)

    zi = [np.zeros(NTAPS - 1)]
    one = np.empty(1)

    def lf(v: float) -> float:
        one[0] = v
        y, zi[0] = lfilter(taps, 1.0, one, zi=zi[0])
        return float(y[0])

    t_lfilter = _per_tick_us(lf, x)

    hist = np.zeros(NTAPS)

    def conv(v: float) -> float:
        hist[:-1] = hist[1:]
        hist[-1] = v
        return float(np.convolve(hist, taps, "valid")[0])

    t_conv = _per_tick_us(conv, x)

    xa = np.asarray(x)
    t0 = time.perf_counter()
    fir_filter(taps, xa)
    t_block = (time.perf_counter() - t0) / xa.size * 1e6

    print(f"live inverse, {NTAPS} taps, per tick:")
    print(f"  InverseFilter.tick (ring + one dot)     {t_live:7.2f} us")
    print(f"  scipy lfilter per sample, zi carried    {t_lfilter:7.2f} us  "
          f"(ratio {t_lfilter / t_live:.1f}x)")
    print(f"  shift history + np.convolve per tick    {t_conv:7.2f} us  "
          f"(ratio {t_conv / t_live:.1f}x)")
    print(f"  fir_filter block, per sample            {t_block:7.3f} us")
    print(f"  share of a 1 ms tick: {t_live / 10:.2f} %")


if __name__ == "__main__":
    main()
