"""Tracking cost per 640x480 frame, decoding excluded, on one core.

Compares in the same run:
- ``numpy-paper``: a plain NumPy implementation of the paper's method (the baseline);
- ``paper``: the project's paper method (OpenCV resize and grey levels);
- ``robust``: the project's default tracker.

The methods are timed in turn, pass by pass over the same decoded frames, and each keeps
its best pass: a burst of load on a shared machine then hits all of them alike instead of
one method's whole measurement.

Usage: python benchmarks/bench_tracking.py [RECDIR] [--frames N] [--repeats N]
Targets: robust >= 1000 frames/s and >= 2x faster than numpy-paper.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from vision.contact import ContactTracker
from vision.recording import PadRecording

REPO = Path(__file__).resolve().parents[1]


def numpy_paper(frame, roi_px, workspace_mm, image_flip, threshold=150, beta=5.0,
                size=(160, 120)):
    """The paper's method written with NumPy only: the baseline a lab would write."""
    if image_flip in ("horizontal", "both"):
        frame = frame[:, ::-1]
    if image_flip in ("vertical", "both"):
        frame = frame[::-1]
    x, y, w, h = roi_px
    roi = frame[y : y + h, x : x + w].astype(np.float64)
    grey = roi @ np.array([0.114, 0.587, 0.299])  # BGR weights of ITU-R BT.601
    # Area resize: mean over the block of source pixels each target cell covers.
    rows = (np.arange(size[1] + 1) * h / size[1]).astype(int)
    cols = (np.arange(size[0] + 1) * w / size[0]).astype(int)
    sums = np.add.reduceat(np.add.reduceat(grey, rows[:-1], axis=0), cols[:-1], axis=1)
    small = sums / np.outer(np.diff(rows), np.diff(cols))
    mask = small < threshold
    if not mask.any():
        return None
    vals = small[mask]
    lo, hi = vals.min(), vals.max()
    sigma = (hi - lo) / beta
    k = np.exp(-((vals - lo) ** 2) / (2 * sigma**2)) if sigma > 0 else np.ones_like(vals)
    jj, ii = np.nonzero(mask)
    u = x + (np.sum(k * (ii + 0.5)) / k.sum()) * w / size[0]
    v = y + (np.sum(k * (jj + 0.5)) / k.sum()) * h / size[1]
    return ((u - x) / w - 0.5) * workspace_mm[0], (0.5 - (v - y) / h) * workspace_mm[1]


def time_per_frame(fns: dict, frames, repeats: int) -> dict[str, float]:
    """Best seconds per frame of each function, the functions run in turn each pass."""
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            for f in frames:
                fn(f)
            best[name] = min(best[name], (time.perf_counter() - t0) / len(frames))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("recdir", nargs="?", default=str(REPO / "recordings" / "circle"))
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=7, help="passes per method (best kept)")
    args = ap.parse_args()
    cv2.setNumThreads(1)  # one core, as the target says
    rec = PadRecording(args.recdir)
    frames = [f for _, _, f in rec.frames()][: args.frames]
    m = rec.meta
    print(f"{len(frames)} frames of {rec.video_size[0]}x{rec.video_size[1]} from {args.recdir} "
          "(decoded before timing)")

    def run_tracker(method):
        tracker = ContactTracker(roi_px=m.roi_px, workspace_mm=m.workspace_mm,
                                 image_flip=m.image_flip, method=method)

        def fn(frame):
            return tracker.process(frame)
        return fn

    results = time_per_frame({
        "numpy-paper (baseline)":
            lambda f: numpy_paper(f, m.roi_px, m.workspace_mm, m.image_flip),
        "paper": run_tracker("paper"),
        "robust": run_tracker("robust"),
    }, frames, args.repeats)
    baseline = results["numpy-paper (baseline)"]
    print(f"{'method':<24}{'us/frame':>10}{'frames/s':>10}{'vs baseline':>13}")
    for name, t in results.items():
        print(f"{name:<24}{t * 1e6:>10.0f}{1 / t:>10.0f}{baseline / t:>12.1f}x")
    robust = results["robust"]
    print(f"robust: {'meets' if 1 / robust >= 1000 else 'MISSES'} >= 1000 frames/s, "
          f"{'meets' if baseline / robust >= 2 else 'MISSES'} >= 2x baseline")


if __name__ == "__main__":
    main()
