"""Texture benchmarks, run on demand: ``python benchmarks/bench_texture.py``.

Each figure is printed beside a baseline measured in the same run:
- block synthesis of 1 s at order 200 (target <= 1 ms, i.e. >= 1000x real time) against
  a naive Python loop of eq. 5;
- the per-sample path ``TextureRenderer.tick`` (target <= 20 us) against the same loop;
  both for the calibrated form (``"stretch"``, FIR structure) and the paper's per-speed
  fits (``"nearest"``, eq. 5 direct form);
- fitting one speed from 10 s of 1 kHz data (target <= 100 ms) against scipy's Toeplitz
  solve on NumPy's autocorrelation, and a whole texture by either form.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sl
from timing import best

from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.lpc.analysis import lpc_autocorrelation
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import fit_paper, fit_texture
from fydpad.texture.lpc.synthesis import TextureRenderer


def _scipy_lpc(x: np.ndarray, order: int) -> np.ndarray:
    r = np.correlate(x, x, "full")[x.size - 1:x.size + order] / x.size
    return np.concatenate([[1.0], sl.solve_toeplitz(r[:order], -r[1:])])


def main() -> None:
    warnings.simplefilter("ignore")
    fs = 1000.0
    scans = {s: generate_scan("canvas", s, 11.0, seed=1) for s in (10.0, 20.0, 30.0, 40.0)}
    print("texture benchmarks (order 200, 1 kHz)")

    # Fitting one speed from 10 s.
    x = preprocess(scans[20.0].acc, fs)[500:10_500]
    t_fit = best(lambda: lpc_autocorrelation([x], 200))
    t_base = best(lambda: _scipy_lpc(x, 200), 3)
    t_pre = best(lambda: preprocess(scans[20.0].acc[:10_000], fs), 3)
    print(f"  fit one speed, 10 s: {t_fit * 1e3:.1f} ms (target <= 100 ms); "
          f"np.correlate + solve_toeplitz baseline {t_base * 1e3:.1f} ms "
          f"({t_base / t_fit:.1f}x); + high-pass and DFT321 of the 3 axes {t_pre * 1e3:.1f} ms")

    sc = list(scans.values())
    t_paper = best(lambda: fit_paper(sc), 3)
    t_cal = best(lambda: fit_texture(sc), 3)
    models = {"paper": fit_paper(sc), "calibrated": fit_texture(sc)}
    print(f"  fit a whole texture (4 speeds x 11 s, incl. preprocessing): calibrated "
          f"{t_cal * 1e3:.0f} ms, the paper's per-speed fits {t_paper * 1e3:.0f} ms "
          f"({t_cal / t_paper:.1f}x)")

    h = models["paper"].h[20]
    sigma = 0.03

    def naive(n: int = 1000) -> None:
        hist = [0.0] * 200
        rng = np.random.default_rng(0)
        for _ in range(n):
            y = sigma * rng.standard_normal() + sum(c * a for c, a in zip(h, hist, strict=True))
            hist.insert(0, y)
            hist.pop()

    t_naive = best(lambda: naive(200), 3) * 5
    n = 20_000
    speeds = 10.0 + 30.0 * np.random.default_rng(1).random(n)
    hand_long = generate_scan("canvas", 25.0, 24.0, seed=50).speed_mm_s[2000:22000]
    # Each form's renderer (the calibrated FIR, the paper's eq. 5 direct form), each with
    # the naive loop as baseline.
    for form, model in models.items():
        t_build = best(lambda m=model: TextureRenderer(m, seed=0), 3)
        r = TextureRenderer(model, seed=0)
        r.warmup(25.0)
        t_block = best(lambda r=r: r.block(25.0, True, 1000), 50)
        v = np.linspace(10.0, 40.0, 1000)
        t_vary = best(lambda r=r, v=v: r.block(v, True), 20)
        # A hand's stroke: the speed trace of a generated 25 mm/s scan (wander, sway),
        # ~17 table entries a second; the same stroke by tick as the baseline.
        # Consecutive seconds of one stroke: repeating one second would jump the speed
        # back to its start each time, a start the FIR warps (lag_speeds) as a hand's does.
        pieces = iter(np.array_split(hand_long, 20))
        r.warmup(float(hand_long[0]))
        t_hand = best(lambda r=r, pieces=pieces: r.block(next(pieces), True), 20)

        tick_pieces = iter(np.array_split(hand_long, 20))
        r.warmup(float(hand_long[0]))

        def hand_ticks(r=r, pieces=tick_pieces) -> None:
            for s in next(pieces):
                r.tick(float(s), True)

        t_hand_tick = best(hand_ticks, 5)
        what = f"{form}/{r.interpolation}/{r.structure}"
        print(f"  [{what}] renderer start-up (speed table): {t_build * 1e3:.0f} ms")
        print(f"  [{what}] block synthesis, 1 s at constant speed: {t_block * 1e3:.3f} ms = "
              f"{1 / t_block:.0f}x real time (target >= 1000x); speed sweeping 10-40 mm/s "
              f"through {r.table.h.shape[0]} table filters: "
              f"{t_vary * 1e3:.2f} ms = {1 / t_vary:.0f}x; naive Python loop "
              f"{t_naive * 1e3:.0f} ms ({t_naive / t_block:.0f}x slower)")
        print(f"  [{what}] block synthesis, 1 s along a hand's stroke (25 mm/s, wandering): "
              f"{t_hand * 1e3:.2f} ms = {1 / t_hand:.0f}x real time (target >= 1000x); "
              f"the same stroke by tick {t_hand_tick * 1e3:.1f} ms "
              f"({t_hand_tick / t_hand:.1f}x slower)")
        tick = r.tick

        def ticks(tick=tick) -> None:
            for s in speeds:
                tick(s, True)

        t_tick = best(ticks, 3) / n
        print(f"  [{what}] per-sample tick (speed changing every tick): "
              f"{t_tick * 1e6:.2f} us/sample (target <= 20 us); naive loop "
              f"{t_naive / 1000 * 1e6:.0f} us/sample ({t_naive / 1000 / t_tick:.0f}x slower)")


def quality(textures: list[str] | None = None) -> None:
    """Held-out figures of both forms against the texture targets for every texture
    (minutes; --quality)."""
    from fydpad.synth.texture_scans import TEXTURES
    from fydpad.texture.evaluation.evaluate import evaluate_family, evaluate_second
    from fydpad.texture.evaluation.identify import identify_families
    from fydpad.texture.lpc.family import LpcFamily

    warnings.simplefilter("ignore")
    names = textures or list(TEXTURES)
    forms = ("paper", "calibrated")
    rows: dict[tuple[str, float], list] = {}
    models: dict[str, list] = {f: [] for f in forms}
    for name in names:
        train = [generate_scan(name, s, 8.0, seed=k) for s in (10.0, 20.0, 30.0, 40.0)
                 for k in (1, 2)]
        fitted = {"paper": fit_paper(train), "calibrated": fit_texture(train)}
        for f in forms:
            models[f].append(fitted[f])
        for v in (10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0):
            held = generate_scan(name, v, 10.0, seed=100)
            second = generate_scan(name, v, 10.0, seed=200)
            cal = LpcFamily(fitted["calibrated"])
            mask = cal.covers(held.speed_mm_s)
            ceil = evaluate_second(cal, held, second, mask)
            res = [ceil.psd_correlation, ceil.lsd_db]
            for f in forms:
                c, *_ = evaluate_family(LpcFamily(fitted[f]), held, mask=mask)
                res += [c.psd_correlation, c.lsd_db]
            rows[(name, v)] = res
            print(f"  {name:15s} {v:4.0f} mm/s  ceiling corr {res[0]:.3f} LSD {res[1]:.2f} | "
                  + " | ".join(f"{f} {res[2 + 2 * i]:.3f} {res[3 + 2 * i]:.2f}"
                               for i, f in enumerate(forms)), flush=True)
    print("summary (mean over textures; 'ok' = corr >= 0.95 and LSD <= ceiling + 0.25 dB)")
    for v in (10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0):
        r = np.array([rows[(n, v)] for n in names])
        parts = [f"ceiling LSD {r[:, 1].mean():.2f}"]
        for i, f in enumerate(forms):
            corr, lsd = r[:, 2 + 2 * i], r[:, 3 + 2 * i]
            ok = np.mean((corr >= 0.95) & (lsd <= r[:, 1] + 0.25))
            parts.append(f"{f}: corr {corr.mean():.3f} (min {corr.min():.3f}) "
                         f"LSD {lsd.mean():.2f} ok {ok:.0%}")
        print(f"  {v:4.0f} mm/s  " + "; ".join(parts))
    scans = [generate_scan(n, v, 6.0, seed=300) for n in names for v in (15.0, 25.0, 35.0)]
    for f in forms:
        for d in ("bands", "lsd"):
            fams = [LpcFamily(m) for m in models[f]]
            ident = identify_families(fams, [m.surface for m in fams], scans, distance=d)
            print(f"  identification ({len(names)} textures, 15/25/35 mm/s held-out "
                  f"strokes), {f}, distance {d}: {ident.rate:.1%}")


if __name__ == "__main__":
    import sys

    if "--quality" in sys.argv:
        quality([a for a in sys.argv[1:] if not a.startswith("--")] or None)
    else:
        main()
