"""Issue 7's held-out figures taken apart (docs/texture.md, "causes per texture" and
"Identification: third-octave band levels"). Minutes each; prints, asserts nothing.

    python benchmarks/texture_causes.py modelled [SPEED] [TEXTURES]   # default 30 mm/s, all
    python benchmarks/texture_causes.py between [TEXTURES]            # 25 mm/s, R1,R2
    python benchmarks/texture_causes.py identify TRAIN_SEED HELD_SEED SPEEDS [TRAIN_S HELD_S]

``modelled``: test_targets.py's every_texture set-up (one 5 s training stroke per speed,
held-out 4 s stroke seed 50, ceiling seed 51), the gap (LSD - ceiling) and correlation
of the default fit, of 3x the data, of the two-part model and of both.
``between``: test_targets.py's figures set-up (8 s strokes) at 25 mm/s, two-part: the
ceiling over four second recordings, and the bias of 4 synthesized realisations per
40 Hz band. ``identify``: rate and closest call with both distances (bands, lsd).
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import compare, evaluate_scan, evaluation_mask, welch_psd
from fydpad.texture.fit import fit_texture
from fydpad.texture.identify import identify
from fydpad.texture.scan_generator import TEXTURES, generate_scan
from fydpad.texture.synthesis import synthesize

SPEEDS = (10.0, 20.0, 30.0, 40.0)


def modelled(speed: float, names: list[str]) -> None:
    for n in names:
        t1 = [generate_scan(n, s, 5.0, seed=1) for s in SPEEDS]
        t3 = t1 + [generate_scan(n, s, 5.0, seed=k) for s in SPEEDS for k in (2, 3)]
        held = generate_scan(n, speed, 4.0, seed=50)
        second = generate_scan(n, speed, 4.0, seed=51)
        base = fit_texture(t1)[0]
        mask = evaluation_mask(held, base)
        ceil, *_ = compare(preprocess(held.acc, 1000.0), preprocess(second.acc, 1000.0),
                           1000.0, mask & evaluation_mask(second, base))
        row = []
        for label, model in (("default", base), ("3x data", fit_texture(t3)[0]),
                             ("two-part", fit_texture(t1, two_part=True)[0]),
                             ("two-part 3x", fit_texture(t3, two_part=True)[0])):
            c, _ = evaluate_scan(model, held, method="stretch", mask=mask)
            row.append(f"{label} {c.lsd_db - ceil.lsd_db:+.2f}/{c.psd_correlation:.3f}")
        print(f"{n:15s} ceiling {ceil.lsd_db:.2f}/{ceil.psd_correlation:.3f}  "
              + "  ".join(row), flush=True)


def between(names: list[str], speed: float = 25.0) -> None:
    for n in names:
        t1 = [generate_scan(n, s, 8.0, seed=1) for s in SPEEDS]
        model = fit_texture(t1, two_part=True)[0]
        held = generate_scan(n, speed, 8.0, seed=100)
        mask = evaluation_mask(held, model)
        rec = preprocess(held.acc, 1000.0)
        seconds = [generate_scan(n, speed, 8.0, seed=k) for k in (200, 201, 202, 203)]
        ceils = [compare(rec, preprocess(s.acc, 1000.0), 1000.0,
                         mask & evaluation_mask(s, model))[0].lsd_db for s in seconds]
        c, _ = evaluate_scan(model, held, method="stretch", mask=mask)
        f, pr = welch_psd(rec, 1000.0, mask)
        ps = np.mean([welch_psd(synthesize(model, held.speed_mm_s, seed=k, method="stretch"),
                                1000.0, mask)[1] for k in range(4)], axis=0)
        d = 10 * np.log10(ps / pr)
        bands = " ".join(f"{lo}:{np.mean(d[(f >= lo) & (f < lo + 40)]):+.1f}"
                         for lo in range(20, 500, 40))
        print(f"{n}: ceilings {np.round(ceils, 2)}; gap {c.lsd_db - ceils[0]:+.2f} (seed 200), "
              f"{c.lsd_db - np.mean(ceils):+.2f} (mean); corr {c.psd_correlation:.3f}\n"
              f"  mean of 4 syntheses minus recording, dB per 40 Hz band from: {bands}",
              flush=True)


def identification(train_seed: int, held_seed: int, speeds: list[float],
                   train_s: float = 5.0, held_s: float = 4.0) -> None:
    models = [fit_texture([generate_scan(n, s, train_s, seed=train_seed) for s in SPEEDS])[0]
              for n in TEXTURES]
    scans = [generate_scan(n, v, held_s, seed=held_seed) for n in TEXTURES for v in speeds]
    for method in ("stretch", "lsf", "linear"):
        for distance in ("bands", "lsd"):
            r = identify(models, scans, method=method, distance=distance)
            margins = []
            for a in r.assignments:
                d = a["distance_db"]
                own = d[a["label"]]
                other = min(v for k, v in d.items() if k != a["label"])
                margins.append(((other - own) / own, a["scan"]))
            worst = min(margins)
            missed = [f"{a['scan']} -> {a['predicted']}" for a in r.assignments
                      if a["predicted"] != a["label"]]
            print(f"{method}/{distance}: {round(r.rate * len(scans))}/{len(scans)}, closest "
                  f"{worst[1]} {worst[0]:+.0%}; missed {missed}", flush=True)


if __name__ == "__main__":
    warnings.simplefilter("ignore")
    what, args = sys.argv[1], sys.argv[2:]
    if what == "modelled":
        modelled(float(args[0]) if args else 30.0,
                 args[1].split(",") if len(args) > 1 else list(TEXTURES))
    elif what == "between":
        between(args[0].split(",") if args else ["R1", "R2"])
    elif what == "identify":
        identification(int(args[0]), int(args[1]), [float(v) for v in args[2].split(",")],
                       *(float(a) for a in args[3:5]))
    else:
        raise SystemExit(__doc__)
