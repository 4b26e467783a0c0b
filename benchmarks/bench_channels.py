"""Streaming resampler throughput vs scipy.signal.resample_poly one-shot, same run.

    nice python benchmarks/bench_channels.py
"""

from __future__ import annotations

import time

import numpy as np
from scipy.signal import resample_poly

from fydpad.channels.resample import Resampler


def _best(fn, reps: int = 3) -> float:
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    x = np.random.default_rng(0).standard_normal(10_000)  # 10 s at 1 kHz
    for fout in (48000, 44100):
        r0 = Resampler(1000, fout)
        up, down = r0.up, r0.down

        def streamed(fout=fout) -> None:
            r = Resampler(1000, fout)
            for b in np.split(x, len(x) // 10):  # 10 ms blocks, as the render loop would
                r.process(b)

        t_s = _best(streamed)
        t_ref = _best(lambda up=up, down=down: resample_poly(x, up, down))
        print(f"1000 -> {fout} Hz ({up}/{down}): streamed 10-ms blocks "
              f"{len(x) / t_s:,.0f} in-samples/s ({len(x) * up / down / t_s:,.0f} out/s); "
              f"resample_poly one-shot {len(x) / t_ref:,.0f} in/s; ratio {t_s / t_ref:.2f}x "
              f"slower; real-time factor {len(x) / 1000 / t_s:.0f}x")


if __name__ == "__main__":
    main()
