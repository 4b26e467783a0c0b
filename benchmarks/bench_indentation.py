"""Indentation accuracy against the true depth: the paper's plane (eq. 2) and the fitted
correction, over 0-50 mm, on a fabric that is not a plane.

Data, either:
- the analytic membrane of tests/sensing/fabric_model.py (default): presses uniform over
  the 100 x 70 mm workspace and 0-50 mm, IR noise 4 mV, 10-bit ADC; or
- pad session recordings with ``ir.csv`` and ``truth.csv`` (``--recordings``), e.g. from
  the synthetic pad: the truth's centroid and contact are used, so the figure is the
  indentation method's alone, not the tracker's.

The correction is fitted on one half of the presses (or recordings) and scored on the
other half, then the other way round; the figure is the held-out RMSE.

Usage: python benchmarks/bench_indentation.py [--presses N] [--recordings RECDIR ...]
Target: RMSE <= 3 mm over 0-50 mm (paper: 2.88 mm).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from vision.indentation import (  # noqa: E402
    IndentationEstimator,
    IRFlag,
    SagCorrection,
    indentation_at_frames,
    rmse,
)
from vision.recording import PadRecording  # noqa: E402
from vision.stream import recording_estimator  # noqa: E402


def membrane_data(n: int, seed: int):
    from tests.sensing.fabric_model import MembraneFabric, random_presses, synth_ir

    rng = np.random.default_rng(seed)
    baseline = (99.0, 101.0, 100.5)
    x, y, d = random_presses(n, rng)
    v = synth_ir(MembraneFabric(), x, y, d, rng, baseline)
    est = IndentationEstimator(baseline_mm=baseline)
    r = est.estimate(v, x, y)
    groups = np.arange(n) % 2
    return r.plane_mm, r.deflection_mm, r.flags, x, y, d, groups, est, v


def recording_data(paths: list[str]):
    planes, es, flags, xs, ys, ds, groups = [], [], [], [], [], [], []
    for k, p in enumerate(paths):
        rec = PadRecording(p)
        ir, truth = rec.read_ir(), rec.read_truth()
        if ir is None or truth is None:
            raise SystemExit(f"{p}: needs ir.csv and truth.csv")
        r, _ = indentation_at_frames(recording_estimator(rec), ir[0], ir[1], truth.t_s,
                                     truth.contact, truth.x_mm, truth.y_mm)
        c = truth.contact
        planes.append(r.plane_mm[c])
        es.append(r.deflection_mm[c])
        flags.append(r.flags[c])
        xs.append(truth.x_mm[c])
        ys.append(truth.y_mm[c])
        ds.append(truth.indentation_mm[c])
        # One recording: alternate presses (contact runs) between the halves.
        run = np.cumsum(np.diff(np.concatenate([[0], c.astype(int)])) == 1)[c]
        groups.append(run % 2 if len(paths) == 1 else np.full(int(c.sum()), k % 2))
    return tuple(np.concatenate(a) for a in (planes, es, flags, xs, ys, ds, groups))


def report(plane, e, flags, x, y, d, groups) -> None:
    ok = (flags & int(IRFlag.INVALID_V0 | IRFlag.INVALID_V1 | IRFlag.INVALID_V2)) == 0
    ok &= d <= 50.0
    corrected = np.full_like(plane, np.nan)
    for g in (0, 1):
        fit = ok & (groups == g)
        score = ok & (groups != g)
        corr = SagCorrection.fit(e[fit], x[fit], y[fit], d[fit])
        corrected[score] = corr.apply(e[score], x[score], y[score])
    print(f"samples {int(ok.sum())} valid of {ok.size}; flat-region readings "
          f"{np.mean((flags & int(IRFlag.FLAT_REGION)) != 0) * 100:.1f} %")
    print(f"{'depth [mm]':>12} {'n':>6} {'plane RMSE':>11} {'corrected':>10}")
    for lo in range(0, 50, 10):
        m = ok & (d >= lo) & (d < lo + 10)
        print(f"{lo:>5}-{lo + 10:<6} {int(m.sum()):>6} {rmse(plane[m], d[m]):>11.2f} "
              f"{rmse(corrected[m], d[m]):>10.2f}")
    print(f"{'0-50':>12} {int(ok.sum()):>6} {rmse(plane[ok], d[ok]):>11.2f} "
          f"{rmse(corrected[ok], d[ok]):>10.2f}   (mm; paper's plane: 2.88)")
    inside = ok & (np.abs(x) <= 22) & (y >= -3) & (y <= 27)
    print(f"bias of the plane for presses over 30 mm near the sensors: "
          f"{np.mean(plane[inside & (d > 30)] - d[inside & (d > 30)]):+.2f} mm")


def timing(est: IndentationEstimator, v: np.ndarray) -> None:
    x = np.zeros(len(v))
    t0 = time.perf_counter()
    est.estimate(v, x, x)
    t1 = time.perf_counter()
    for k in range(200):
        est.estimate_one(v[k], 0.0, 0.0)
    t2 = time.perf_counter()
    print(f"cost: vectorised {(t1 - t0) / len(v) * 1e6:.2f} us/sample, per-sample path "
          f"{(t2 - t1) / 200 * 1e6:.1f} us/sample")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presses", type=int, default=20000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--recordings", nargs="+", metavar="RECDIR")
    args = ap.parse_args()
    if args.recordings:
        print(f"recordings: {', '.join(args.recordings)}")
        report(*recording_data(args.recordings))
        return
    plane, e, flags, x, y, d, groups, est, v = membrane_data(args.presses, args.seed)
    print(f"analytic membrane (tests/sensing/fabric_model.py), {args.presses} presses")
    report(plane, e, flags, x, y, d, groups)
    timing(est, v)


if __name__ == "__main__":
    main()
