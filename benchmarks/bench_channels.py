"""Streaming resampler throughput vs scipy.signal.resample_poly one-shot, same run; and the
cost of one 1 ms block written to the audio channel's ring (what the 1 kHz loop pays).

    nice python benchmarks/bench_channels.py
"""

from __future__ import annotations

import time

import numpy as np
from scipy.signal import resample_poly

from fydpad.channels.resample import Resampler
from fydpad.channels.ring import RingFeed


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


def bench_ring_write(rate_in_hz: float, rate_out_hz: float, n_blocks: int = 20_000) -> None:
    """RingFeed.write of one 1 ms block (resample, clip, push), the card's callback draining
    the ring every 10 ms as a 480-frame PortAudio buffer would; per-write times."""
    feed = RingFeed(rate_in_hz, rate_out_hz, capacity_frames=round(0.5 * rate_out_hz),
                    prefill_frames=round(0.02 * rate_out_hz))
    per_block = round(rate_in_hz / 1000)
    x = np.random.default_rng(1).standard_normal(n_blocks * per_block) * 0.2
    out = np.empty(round(rate_out_hz / 100), np.float32)
    times = np.empty(n_blocks)
    for k in range(n_blocks):
        blk = x[k * per_block:(k + 1) * per_block]
        t0 = time.perf_counter()
        feed.write(blk)
        times[k] = time.perf_counter() - t0
        if k % 10 == 9:
            feed.fill(out)
    us = times * 1e6
    print(f"audio ring write, 1 ms block {rate_in_hz:g} -> {rate_out_hz:g} Hz "
          f"({per_block} in, ~{rate_out_hz / 1000:g} out): median {np.median(us):.1f} us, "
          f"p99 {np.percentile(us, 99):.1f} us, max {us.max():.0f} us "
          f"({np.median(us) / 10:.2f} % of the 1 ms tick); dropped {feed.n_dropped}, "
          f"underruns {feed.n_underruns}")


if __name__ == "__main__":
    main()
    for rates in ((1000, 48000), (1000, 44100), (48000, 48000)):
        bench_ring_write(*rates)
