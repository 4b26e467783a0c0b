"""Texture benchmarks, run on demand: ``python benchmarks/bench_texture.py``.

Each figure is printed beside a baseline measured in the same run:
- block synthesis of 1 s at order 200 (target <= 1 ms, i.e. >= 1000x real time) against
  a naive Python loop of eq. 5;
- the per-sample path ``TextureRenderer.tick`` (target <= 20 us) against the same loop;
  both for the default (``"stretch"``, FIR structure) and the previous ``"lsf"`` (eq. 5);
- fitting one speed from 10 s of 1 kHz data (target <= 100 ms) against Burg's method, and
  the calibrated form's whole fit of one speed against the pooled fit's.
"""

from __future__ import annotations

import warnings

import numpy as np
from timing import best

from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.dft321 import preprocess
from fydpad.texture.fit import fit_speed
from fydpad.texture.lpc import h_from_poly
from fydpad.texture.model_file import TextureModel
from fydpad.texture.synthesis import TextureRenderer


def main() -> None:
    warnings.simplefilter("ignore")
    fs = 1000.0
    scans = {s: generate_scan("canvas", s, 11.0, seed=1) for s in (10.0, 20.0, 30.0, 40.0)}
    xs = {s: preprocess(sc.acc, fs)[500:10_500] for s, sc in scans.items()}
    polys = {s: fit_speed([x], 200)[0] for s, x in xs.items()}
    model = TextureModel("canvas", fs, np.array(sorted(polys)),
                         np.vstack([h_from_poly(polys[s]) for s in sorted(polys)]),
                         np.full(4, 1e-3))
    print("texture benchmarks (order 200, 1 kHz)")

    # Fitting one speed from 10 s.
    x = xs[20.0]
    t_fit = best(lambda: fit_speed([x], 200))
    t_burg = best(lambda: fit_speed([x], 200, "burg"), 3)
    t_pre = best(lambda: preprocess(scans[20.0].acc[:10_000], fs), 3)
    print(f"  fit one speed, 10 s: {t_fit * 1e3:.1f} ms (target <= 100 ms); "
          f"Burg baseline {t_burg * 1e3:.1f} ms ({t_burg / t_fit:.1f}x); "
          f"+ high-pass and DFT321 of the 3 axes {t_pre * 1e3:.1f} ms")

    # The two-part model (fit_texture(two_part=True)): a whole texture, and its load.
    from fydpad.texture.fit import fit_texture

    sc = list(scans.values())
    # The forms on the whole signal (canvas is periodic: lines_benchmark has the lines).
    t_pooled = best(lambda: fit_texture(sc, free_form=None, lines="off"), 3)
    t_two = best(lambda: fit_texture(sc, two_part=True, lines="off"), 3)
    t_default = best(lambda: fit_texture(sc, lines="off"), 3)  # the calibrated form
    two, _ = fit_texture(sc, two_part=True, lines="off")
    t_load = best(lambda: TextureRenderer(two, seed=0), 3)
    t_load_pooled = best(lambda: TextureRenderer(fit_texture(sc, free_form=None,
                                                        lines="off")[0], seed=0),
                         3) - t_pooled
    print(f"  fit a whole texture (4 speeds x 11 s, incl. preprocessing): two-part "
          f"{t_two * 1e3:.0f} ms, calibrated (the default) {t_default * 1e3:.0f} ms, "
          f"pooled LPC {t_pooled * 1e3:.0f} ms; renderer "
          f"start-up (121-entry table): two-part {t_load * 1e3:.0f} ms, pooled/stretch "
          f"{t_load_pooled * 1e3:.0f} ms")
    # The calibrated form (fit --free-form) on one speed from 10 s, as the target reads.
    one = [scans[20.0]]
    t_cal1 = best(lambda: fit_texture(one, speeds_mm_s=(20.0,), free_form="calibrated",
                                      lines="off"), 3)
    t_pool1 = best(lambda: fit_texture(one, speeds_mm_s=(20.0,), free_form=None, lines="off"),
                   3)
    print(f"  fit one speed from 10 s, whole texture path: calibrated form "
          f"{t_cal1 * 1e3:.0f} ms (target <= 100 ms), pooled {t_pool1 * 1e3:.0f} ms "
          f"({t_cal1 / t_pool1:.1f}x)")

    h = model.h[1]
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
    # The default (stretch interpolation, FIR structure) and the previous default (LSF,
    # eq. 5 direct form), each with the naive loop as baseline.
    for method in ("stretch", "lsf"):
        t_build = best(lambda m=method: TextureRenderer(model, method=m, seed=0), 3)
        r = TextureRenderer(model, method=method, seed=0)
        r.warmup(25.0)
        t_block = best(lambda r=r: r.block(25.0, True, 1000), 50)
        v = np.linspace(10.0, 40.0, 1000)
        t_vary = best(lambda r=r, v=v: r.block(v, True), 20)
        # A hand's stroke: the speed trace of a generated 25 mm/s scan (wander, sway),
        # ~17 table entries a second; the same stroke by tick as the baseline.
        # Consecutive seconds of one stroke: repeating one second would jump the speed
        # back to its start each time, a start the FIR warps (fir_warp) as a hand's does.
        pieces = iter(np.array_split(hand_long, 20))
        r.warmup(float(hand_long[0]))
        t_hand = best(lambda r=r, pieces=pieces: r.block(next(pieces), True), 20)

        tick_pieces = iter(np.array_split(hand_long, 20))
        r.warmup(float(hand_long[0]))

        def hand_ticks(r=r, pieces=tick_pieces) -> None:
            for s in next(pieces):
                r.tick(float(s), True)

        t_hand_tick = best(hand_ticks, 5)
        what = f"{method}/{r.structure}"
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


    lines_benchmark(best)


def lines_benchmark(best) -> None:
    """A periodic surface's lines (fit --lines, the default): the fit, and the renderer
    with its wavetable against the same model without lines, in the same run."""
    from fydpad.texture.fit import fit_texture

    train = [generate_scan("R1", s, 10.0, seed=1 + j) for s in (10.0, 20.0, 30.0, 40.0)
             for j in range(2)]
    one = [generate_scan("R1", 20.0, 11.0, seed=1)]
    t_fit = best(lambda: fit_texture(train), 3)
    t_off = best(lambda: fit_texture(train, lines="off", free_form=None), 3)
    t_one = best(lambda: fit_texture(one, speeds_mm_s=(20.0,)), 3)
    t_one_off = best(lambda: fit_texture(one, speeds_mm_s=(20.0,), lines="off"), 3)
    model, _ = fit_texture(train)
    plain, _ = fit_texture(train)
    plain.lines = None
    n_h = len(model.lines["phase_rad"])
    print(f"  [lines] R1 ({n_h} harmonics, period {model.lines['period_mm']:.4f} mm): fit a "
          f"whole texture (8 strokes of 10 s) {t_fit:.2f} s, without lines {t_off:.2f} s; "
          f"one speed from 11 s {t_one * 1e3:.0f} ms (target <= 100 ms), without lines "
          f"{t_one_off * 1e3:.0f} ms")
    hand = generate_scan("R1", 25.0, 24.0, seed=50).speed_mm_s[2000:22000]
    for label, m in (("with lines", model), ("without", plain)):
        # Consecutive seconds of one stroke (as the main benchmark), by block then by tick.
        r = TextureRenderer(m, seed=0)
        r.warmup(float(hand[0]))
        pieces = iter(np.array_split(hand, 20))
        t_block = best(lambda r=r, pieces=pieces: r.block(next(pieces), True), 20)
        r.warmup(float(hand[0]))
        tick_pieces = iter(np.array_split(hand, 20))

        def ticks(r=r, pieces=tick_pieces) -> None:
            for s in next(pieces):
                r.tick(float(s), True)

        t_tick = best(ticks, 5) / 1000
        extra = "" if r.lines is None else (f"; wavetable {r.lines.table.shape[0]} x "
                                            f"{r.lines.table.shape[1]}, "
                                            f"{r.lines.table.nbytes / 1e6:.1f} MB")
        print(f"  [lines] R1 {label}: block along a hand's stroke 1 s {t_block * 1e3:.2f} ms"
              f" = {1 / t_block:.0f}x real time; tick {t_tick * 1e6:.2f} us/sample{extra}")


def quality(textures: list[str] | None = None) -> None:
    """Held-out figures against the texture targets for every texture (minutes; --quality)."""
    from fydpad.synth.texture_scans import TEXTURES
    from fydpad.texture.evaluation.evaluate import (
        compare_recordings,
        evaluate_scan,
        evaluation_mask,
    )
    from fydpad.texture.evaluation.identify import identify
    from fydpad.texture.fit import fit_texture

    warnings.simplefilter("ignore")
    names = textures or list(TEXTURES)
    methods = ("stretch", "lsf", "linear")
    rows: dict[tuple[str, float], list] = {}
    models, two_models = [], []
    for name in names:
        train = [generate_scan(name, s, 8.0, seed=k) for s in (10.0, 20.0, 30.0, 40.0)
                 for k in (1, 2)]
        model, _ = fit_texture(train, free_form=None, lines="off")
        models.append(model)
        norm, _ = fit_texture(train, speeds_mm_s=[10.0 + 5 * k for k in range(7)],
                              speed_normalise=True, lines="off")
        two, _ = fit_texture(train, two_part=True, lines="off")
        two_models.append(two)
        for v in (10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0):
            held = generate_scan(name, v, 10.0, seed=100)
            second = generate_scan(name, v, 10.0, seed=200)
            mask = evaluation_mask(held, model)
            ceil = compare_recordings(held, second, model, mask)
            res = [ceil.psd_correlation, ceil.lsd_db]
            for m in methods:
                c, _ = evaluate_scan(model, held, method=m, mask=mask)
                res += [c.psd_correlation, c.lsd_db]
            c, _ = evaluate_scan(norm, held, method="stretch", mask=mask)
            c2, _ = evaluate_scan(two, held, method="stretch", mask=mask)
            res += [c2.psd_correlation, c2.lsd_db]
            rows[(name, v)] = res
            print(f"  {name:15s} {v:4.0f} mm/s  ceiling corr {res[0]:.3f} LSD {res[1]:.2f} | "
                  + " | ".join(f"{m} {res[2 + 2 * i]:.3f} {res[3 + 2 * i]:.2f}"
                               for i, m in enumerate(methods))
                  + f" | speed-normalised fit, 5 mm/s grid {c.psd_correlation:.3f} "
                  f"{c.lsd_db:.2f} | two-part {c2.psd_correlation:.3f} {c2.lsd_db:.2f}",
                  flush=True)
    print("summary (mean over textures; 'ok' = corr >= 0.95 and LSD <= ceiling + 0.25 dB)")
    for v in (10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0):
        r = np.array([rows[(n, v)] for n in names])
        parts = [f"ceiling LSD {r[:, 1].mean():.2f}"]
        for i, m in enumerate((*methods, "two-part")):
            corr, lsd = r[:, 2 + 2 * i], r[:, 3 + 2 * i]
            ok = np.mean((corr >= 0.95) & (lsd <= r[:, 1] + 0.25))
            parts.append(f"{m}: corr {corr.mean():.3f} (min {corr.min():.3f}) "
                         f"LSD {lsd.mean():.2f} ok {ok:.0%}")
        print(f"  {v:4.0f} mm/s  " + "; ".join(parts))
    scans = [generate_scan(n, v, 6.0, seed=300) for n in names for v in (15.0, 25.0, 35.0)]
    for m in methods:
        for d in ("bands", "lsd"):  # third-octave levels (default), 4 Hz-bin LSD (before)
            ident = identify(models, scans, method=m, distance=d)
            print(f"  identification ({len(names)} textures, 15/25/35 mm/s held-out "
                  f"strokes), {m}, distance {d}: {ident.rate:.1%}")
    for d in ("bands", "lsd"):
        ident = identify(two_models, scans, method="stretch", distance=d)
        print(f"  identification, two-part models, distance {d}: {ident.rate:.1%}")


if __name__ == "__main__":
    import sys

    if "--quality" in sys.argv:
        quality([a for a in sys.argv[1:] if not a.startswith("--")] or None)
    else:
        main()
