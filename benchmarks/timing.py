"""Timing helpers shared by the benchmarks (run as ``python benchmarks/NAME.py``)."""

from __future__ import annotations

import time
from collections.abc import Callable


def best(fn: Callable[[], object], repeat: int = 7) -> float:
    """The shortest of ``repeat`` timed calls of ``fn``, seconds (the least disturbed run
    on a shared machine)."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)
