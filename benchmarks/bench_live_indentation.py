"""The live station's per-frame indentation cost: every IR sample since the last frame
through the ring (``IRBuffer``) and the Kalman filter (``LiveIndentation.update``),
against the newest-sample estimate (``IndentationEstimator.estimate_one``, a zero-order hold) as the
baseline, measured in the same run.

Samples per frame = board rate / vision rate: 100 Hz / 30 fps ~ 3, 100 Hz / 10 Hz = 10,
1 kHz / 30 fps ~ 33, 1 kHz / 10 Hz = 100.

Usage: python benchmarks/bench_live_indentation.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from timing import best  # noqa: E402

from fydpad.station.ir_buffer import IRBuffer  # noqa: E402
from vision.config import IRConfig  # noqa: E402
from vision.contact import Contact  # noqa: E402
from vision.indentation import IndentationEstimator  # noqa: E402
from vision.stream import LiveIndentation  # noqa: E402

FRAMES = 200
REST_V = (1.31, 1.32, 1.30)  # about 100 mm: the fabric at rest


def frame_cost_us(n_per_frame: int) -> tuple[float, float]:
    """(ring push + drain + filter + plane) per frame, and the ring's part, in us."""
    est = IndentationEstimator.from_config(IRConfig(), baseline_mm=(100.0, 100.0, 100.0))
    rng = np.random.default_rng(0)
    volts = np.asarray(REST_V) + 0.006 * rng.standard_normal((FRAMES * n_per_frame, 3))
    rows = [tuple(v) for v in volts.tolist()]
    contact = Contact(5.0, 3.0, 0.0, 0.0, 100.0)
    dt_s = 1.0 / (30.0 * n_per_frame)

    def run(filtering: bool) -> None:
        buf = IRBuffer()
        live = LiveIndentation(est)
        k = 0
        for _f in range(FRAMES):
            for _ in range(n_per_frame):  # the sensor loop's share
                buf.push(k * dt_s, rows[k])
                k += 1
            t, v = buf.drain()
            if filtering:
                live.update(t, v, k * dt_s, contact)

    total = best(lambda: run(True), repeat=5) / FRAMES * 1e6
    ring = best(lambda: run(False), repeat=5) / FRAMES * 1e6
    return total, ring


def newest_cost_us() -> float:
    est = IndentationEstimator.from_config(IRConfig(), baseline_mm=(100.0, 100.0, 100.0))
    return best(lambda: [est.estimate_one(REST_V, 5.0, 3.0) for _ in range(FRAMES)],
                repeat=5) / FRAMES * 1e6


def main() -> None:
    base = newest_cost_us()
    print(f"newest sample (estimate_one, the baseline): {base:.0f} us/frame")
    print("samples/frame | us/frame (ring + filter + plane) | of which ring | x newest")
    for n in (3, 10, 33, 100):
        total, ring = frame_cost_us(n)
        print(f"{n:13d} | {total:32.0f} | {ring:13.0f} | {total / base:8.1f}")


if __name__ == "__main__":
    main()
