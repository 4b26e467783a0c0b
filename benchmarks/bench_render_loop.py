"""The 1 kHz render loop's timing while vision runs at 30 fps, as a thread or a process.

Prints, for each way of running the render loop, the share of ticks on time, jitter
p50/p99 and skipped ticks, with the thread (the baseline) beside it.
Usage: python benchmarks/bench_render_loop.py [--seconds S]
Target: >= 99.5 % on time and p99 jitter <= 0.5 ms.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import queue
import threading
import time

import numpy as np

from fydpad.pacing import LoopTimer
from teleop.realtime import request_realtime
from vision.contact import ContactTracker


def render_loop(results, seconds: float, realtime: bool) -> None:
    if realtime:
        request_realtime(50, cpu=-1)
    timer = LoopTimer(1000.0, "render")
    timer.start()
    end = time.perf_counter() + seconds
    state = np.zeros(200)  # an order-200 filter's worth of work per tick
    h = np.linspace(0.1, 0.0, 200)
    while time.perf_counter() < end:
        timer.wait()
        a = float(h @ state)
        state[1:] = state[:-1]
        state[0] = a * 0.5 + 1e-3
    results.put(timer.stats())


def vision_load(seconds: float) -> None:
    rng = np.random.default_rng(0)
    bare = rng.integers(170, 230, (480, 640, 3), dtype=np.uint8)
    touch = bare.copy()
    touch[200:240, 300:340] = 40
    tracker = ContactTracker(image_flip="horizontal")
    timer = LoopTimer(30.0, "vision")
    timer.start()
    end = time.perf_counter() + seconds
    k = 0
    while time.perf_counter() < end:
        timer.wait()
        tracker.process(bare if k % 60 < 30 else touch)
        k += 1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    rows = []
    q: queue.Queue = queue.Queue()
    th = threading.Thread(target=render_loop, args=(q, args.seconds, False))
    th.start()
    vision_load(args.seconds)
    th.join()
    rows.append(("thread (baseline)", q.get()))
    ctx = mp.get_context("spawn")
    for name, rt in (("process", False), ("process, SCHED_FIFO", True)):
        mq = ctx.Queue()
        p = ctx.Process(target=render_loop, args=(mq, args.seconds, rt))
        p.start()
        vision_load(args.seconds)
        rows.append((name, mq.get()))
        p.join()
    base_late = 100 - rows[0][1].on_time_pct
    print(f"{'render loop as':<24}{'on time %':>10}{'p50 ms':>8}{'p99 ms':>8}{'skipped':>9}"
          f"{'late ticks vs thread':>22}")
    for name, s in rows:
        late = 100 - s.on_time_pct
        ratio = f"{late / base_late:.2f}x" if base_late > 0 else "-"
        print(f"{name:<24}{s.on_time_pct:>10.2f}{s.jitter_ms['p50']:>8.2f}"
              f"{s.jitter_ms['p99']:>8.2f}{s.skipped:>9d}{ratio:>22}")


if __name__ == "__main__":
    main()
