"""Indentation on test pads unlike the default (``fydpad.synth.fabrics.TEST_PADS``):
the correction fitted on tapping sessions alone, scored on unseen slides, taps and
Lissajous strokes, against eq. (2)'s plane.

Per pad: three 20 s tapping sessions (seeds 101-103) fit the per-sensor correction
(``PlaneCorrection.fit_cv`` with the sensors' deflections, the ridge by two-fold
cross-validation over presses, as ``fydpad calibrate indentation`` does); 20 s sessions
of ``walk`` (slides), ``tapping`` and ``lissajous`` with other seeds score it. Both go
through the causal filter of ``fydpad track`` (``indentation_samples`` fits on its
readings; the scores are ``CausalIndentation``'s, frame by frame, the correction in the
estimator), so the figures are what a user gets. The true centroids are used, so they
are the indentation's alone.

Usage: python benchmarks/bench_indentation_fabrics.py [--seeds 201 202]
Target: corrected RMSE <= 1.0 mm on every pad and trajectory.
"""

from __future__ import annotations

import argparse

import numpy as np

from fydpad.synth.fabrics import TEST_PADS, causal_indentation, indentation_samples
from vision.indentation import PlaneCorrection, rmse

CAL_SEEDS = (101, 102, 103)
TRAJECTORIES = ("walk", "tapping", "lissajous")
XY_DEGREE, DEPTH_DEGREE = 3, 2
RIDGES = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)


def calibrate(pad: str) -> tuple[PlaneCorrection, float]:
    """The correction from three tapping sessions of the pad, and its held-out RMSE."""
    parts = [indentation_samples(pad, "tapping", s) for s in CAL_SEEDS]
    offset = 0
    for p in parts:  # presses of different sessions are different presses
        p["press"] = p["press"] + offset
        offset = int(p["press"].max(initial=offset)) + 1
    d = {k: np.concatenate([p[k] for p in parts]) for k in ("e", "x", "y", "depth", "press")}
    corr, held, _ = PlaneCorrection.fit_cv(d["e"], d["x"], d["y"], d["depth"], d["press"],
                                           XY_DEGREE, DEPTH_DEGREE, RIDGES,
                                           sensors_mm=parts[0]["sensors"])
    return corr, held


def score(pad: str, corr: PlaneCorrection, trajectory: str, seed: int) -> tuple[float, float]:
    """(plane RMSE, corrected RMSE through ``fydpad track``'s causal path) in mm on one
    unseen session."""
    s = indentation_samples(pad, trajectory, seed)
    fixed, depth = causal_indentation(pad, trajectory, seed, corr)
    return rmse(s["plane"], s["depth"]), rmse(fixed, depth)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[201])
    args = ap.parse_args()
    print("| pad | held-out taps | " + " | ".join(f"{t} plane / corrected" for t in TRAJECTORIES)
          + " |")
    print("| --- | ---: |" + " ---: |" * len(TRAJECTORIES))
    worst = 0.0
    for pad in TEST_PADS:
        corr, held = calibrate(pad)
        cells = []
        for t in TRAJECTORIES:
            res = np.array([score(pad, corr, t, s) for s in args.seeds])
            plane, fixed = res.max(axis=0)
            worst = max(worst, fixed)
            cells.append(f"{plane:.2f} / **{fixed:.2f}**")
        print(f"| {pad} | {held:.2f} | " + " | ".join(cells) + " |", flush=True)
    print(f"worst corrected RMSE {worst:.2f} mm: {'meets' if worst <= 1.0 else 'MISSES'} "
          "<= 1.0 mm")


if __name__ == "__main__":
    main()
