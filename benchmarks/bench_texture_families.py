"""Texture-family benchmarks, run on demand:
``python benchmarks/bench_texture_families.py``.

The per-tick cost of each family's ``tick`` (the station's 1 kHz render process calls it
once a tick with the station's speed; the budget is the 1 ms tick shared with eq. 3 and
the motors) against the LPC family's tick (order 200) measured in the same run as the
baseline
(the penn family: HaTT-schema files of the orders named, 10 kHz models, 10 model
samples and the anti-alias low-pass per tick);
and the offline ``render`` throughput (x real time) of 10 s at 1 kHz and the audio
channel at 48 kHz.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.families.friction import fit_friction, parse_friction
from fydpad.texture.families.grating import GratingFamily
from fydpad.texture.family import constant_stroke
from fydpad.texture.lpc.family import LpcFamily
from fydpad.texture.lpc.fit import fit_paper


def per_tick_us(fam, n: int = 20_000) -> float:
    ts = np.arange(n) / 1000.0
    xs = (10.0 + 20.0 * np.floor(ts * 30) / 30).tolist()  # 30 fps centroids, held
    ts = ts.tolist()
    t0 = time.perf_counter()
    for t, x in zip(ts, xs, strict=True):
        fam.tick(t, True, x, 5.0, 20.0, 1.0)
    return (time.perf_counter() - t0) / n * 1e6


def penn_family(order_ar: int, order_ma: int, tmp: str):
    """A HaTT-schema file (10 kHz, a 4 x 3 speed x force grid, Delaunay triangles) with
    random stable ARMA models, loaded as ``fydpad run --texture FILE.xml`` does."""
    from scipy.spatial import Delaunay

    from fydpad.synth.hatt import write_penn
    from fydpad.texture.families import load_family
    from fydpad.texture.families.penn.toolkit import PennModelSet

    rng = np.random.default_rng(order_ar)
    s, f = np.meshgrid([10.0, 50.0, 120.0, 250.0], [0.2, 1.0, 3.0], indexing="ij")
    s, f = s.ravel(), f.ravel()
    lsf = lambda k: np.sort(rng.uniform(0.02, 3.1, (s.size, k)), axis=1)  # noqa: E731
    ms = PennModelSet("bench", 10_000.0, s, f, Delaunay(np.column_stack([s, f])).simplices,
                      lsf(order_ar), lsf(order_ma), np.full(s.size, 1e-3),
                      np.ones(s.size), 250.0, 3.0)
    fam = load_family(write_penn(f"{tmp}/Models_bench_{order_ar}_{order_ma}.xml", ms))
    fam.prepare(1000.0)
    return fam


def main() -> None:
    import tempfile

    warnings.simplefilter("ignore")
    scans = [generate_scan("canvas", v, 6.0, seed=1, friction=True) for v in (10.0, 30.0)]
    model = fit_paper(scans, order=200)
    lpc = LpcFamily(model)
    lpc.prepare(1000.0)
    fric = parse_friction(fit_friction(scans[:1]), "bench")
    fams = {"lpc (baseline)": lpc, "friction": fric,
            "grating sine": GratingFamily(2.15, profile="sine"),
            "grating rect": GratingFamily(2.15, profile="rect")}
    with tempfile.TemporaryDirectory() as tmp:
        # HaTT sets: 10 model samples (10 kHz) and the anti-alias low-pass per tick.
        fams["penn AR(20) 10k"] = penn_family(20, 0, tmp)
        fams["penn ARMA(25,5)"] = penn_family(25, 5, tmp)
    base = per_tick_us(lpc)
    print("per tick (us)        figure   / lpc")
    for name, fam in fams.items():
        us = base if fam is lpc else per_tick_us(fam)
        print(f"  {name:18s} {us:7.2f}  {us / base:6.2f}x")
    fb = constant_stroke(20.0, 10.0, 1000.0, x0_mm=fric.x0_mm)
    fa = constant_stroke(20.0, 10.0, 48_000.0, x0_mm=fric.x0_mm)
    print("offline render, 10 s (x real time)")
    for name, fam, finger, ch in (
            ("lpc vibration", lpc, fb, "vibration"),
            ("friction tension", fric, fb, "tension"),
            ("friction audio 48k", fric, fa, "audio"),
            ("grating rect vibration", fams["grating rect"], fb, "vibration"),
            ("grating rect audio 48k", fams["grating rect"], fa, "audio"),
            ("penn AR(20) 10k vibration", fams["penn AR(20) 10k"], fb, "vibration")):
        t0 = time.perf_counter()
        fam.render(finger, ch)
        print(f"  {name:24s} {10.0 / (time.perf_counter() - t0):9.0f}x")


if __name__ == "__main__":
    main()
