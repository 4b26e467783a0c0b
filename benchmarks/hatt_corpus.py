"""The texture fit on an independent corpus: surfaces rendered from Penn HaTT models.

    python benchmarks/hatt_corpus.py DIR [--only "Book,Candle"] [--json OUT.json]

DIR holds HaTT model files (``Models_<material>.xml``, Culbertson, Lopez Delgado and
Kuchenbecker 2014; not shipped: see the README). Per surface, through the project's HaTT
import (fydpad/texture/penn.py) and :func:`scan_generator.penn_scan` (which adds a tool
resonance, contact impacts, the hand's wander and gravity on three axes):

- training: one 30 s hand stroke through plateaus near 10, 20, 30 and 40 mm/s;
- test: a 10 s stroke at about 15, 20, 25 and 35 mm/s (a separate rendering: held out),
  and a second rendering of each as the ceiling.

Fitted two ways on the training stroke: ``fydpad texture fit``'s default (validated
selection, fydpad/texture/select.py) and the paper's method read plainly (fit_paper).
Each is synthesized 10 s at the test speed and scored against the held-out stroke (log-
spectral distance and PSD correlation, 4 Hz bins over 20-500 Hz); identification assigns
each 20 mm/s held-out stroke to the nearest model of all surfaces run. Prints one table
of means, the per-speed figures and the identification; the baseline is the paper's
method, the ceiling the second rendering.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from fydpad.progress import progress
from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import compare
from fydpad.texture.fit import fit_paper
from fydpad.texture.identify import identify
from fydpad.texture.penn import read_penn
from fydpad.texture.scan_generator import hand_speed, penn_scan, plateau_speed
from fydpad.texture.select import _piece, fit_candidate, select_model
from fydpad.texture.synthesis import TextureRenderer

PLATEAUS_MM_S = (10.0, 20.0, 30.0, 40.0)
TEST_MM_S = (15.0, 20.0, 25.0, 35.0)
TRAIN_S, TEST_S = 30.0, 10.0


def surface_scans(path: Path):
    ms = read_penn(path)
    fs = ms.fs_hz
    rng = np.random.default_rng(1)
    train = penn_scan(ms, plateau_speed(PLATEAUS_MM_S, TRAIN_S, fs, rng), seed=1)
    held, second = {}, {}
    for s in TEST_MM_S:
        held[s] = penn_scan(ms, hand_speed(s, TEST_S, fs, rng, 0.3), seed=10 + int(s))
        second[s] = penn_scan(ms, hand_speed(s, TEST_S, fs, rng, 0.3), seed=100 + int(s))
    return ms.name, train, held, second


def score(model, held: dict, second: dict) -> dict:
    """Per test speed: the model's 10 s synthesis at that constant speed against the
    held-out stroke (one renderer per model), and the second rendering (the ceiling)."""
    r = TextureRenderer(model, ramp_s=1e-6)
    out = {}
    for s, h in held.items():
        r.reset()
        r.reseed(0)
        r.warmup(s, 0.5)
        rec = preprocess(h.acc, h.fs_hz, 10.0)
        c, *_ = compare(rec, r.block(s, True, h.t_s.size), h.fs_hz)
        cc, *_ = compare(rec, preprocess(second[s].acc, h.fs_hz, 10.0), h.fs_hz)
        out[f"{s:g}"] = ({"lsd_db": c.lsd_db, "psd_correlation": c.psd_correlation},
                         {"lsd_db": cc.lsd_db, "psd_correlation": cc.psd_correlation})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", type=Path, help="directory of HaTT Models_*.xml files")
    ap.add_argument("--only", help="comma-separated material names (default: every file)")
    ap.add_argument("--json", type=Path, help="write every figure as JSON")
    ap.add_argument("--rows", type=Path,
                    help="append each surface's figures to this JSON-lines file as it is done "
                    "and skip the surfaces it already holds (a long run resumes)")
    args = ap.parse_args(argv)
    only = None if args.only is None else {s.strip() for s in args.only.split(",")}
    # Filtered by file name before any file is opened.
    files = sorted(p for p in args.dir.glob("Models_*.xml")
                   if only is None or p.stem[len("Models_"):] in only)
    if not files:
        print(f"{args.dir}: no Models_*.xml files" + (f" named {args.only}" if only else ""),
              file=sys.stderr)
        return 2
    rows, models, scans20 = [], {"default": [], "paper": []}, []
    done = {}
    if args.rows is not None and args.rows.exists():
        for line in args.rows.read_text().splitlines():
            r = json.loads(line)
            done[r["surface"]] = r
    t0 = time.perf_counter()
    warnings.simplefilter("ignore")  # clamping beyond the fitted speeds: said by fit/synth
    for path in progress(files, desc="surfaces", unit="surface"):
        name, train, held, second = surface_scans(path)
        if name in done:  # its figures from the rows file; refitted for identification
            rows.append(done[name])
            models["default"].append(fit_candidate(done[name]["winner"], [train],
                                                   PLATEAUS_MM_S))
            models["paper"].append(fit_paper([train]))
            scans20.append(held[20.0])
            continue
        default, sel = select_model([train], speeds_mm_s=PLATEAUS_MM_S)
        paper = fit_paper([train])
        row = {"surface": name, "winner": sel.winner, "validated": sel.validated,
               "selection": sel.to_json(), "speeds": {}}
        d, p = score(default, held, second), score(paper, held, second)
        for s in TEST_MM_S:
            k = f"{s:g}"
            row["speeds"][k] = {"default": d[k][0], "paper": p[k][0], "ceiling": d[k][1]}
        rows.append(row)
        if args.rows is not None:
            with args.rows.open("a") as fh:
                fh.write(json.dumps(row, allow_nan=False) + "\n")
        print(f"{name}: chose {sel.winner}; mean LSD default "
              f"{np.mean([v['default']['lsd_db'] for v in row['speeds'].values()]):.2f} dB, "
              f"paper {np.mean([v['paper']['lsd_db'] for v in row['speeds'].values()]):.2f}, "
              f"ceiling {np.mean([v['ceiling']['lsd_db'] for v in row['speeds'].values()]):.2f}",
              flush=True)
        models["default"].append(default)
        models["paper"].append(paper)
        scans20.append(held[20.0])
    # The first 5 s of each 20 mm/s stroke: N x N syntheses, kept short.
    crops = [_piece(sc, 0, round(5 * sc.fs_hz), "5s") for sc in scans20]
    ident = {k: identify(m, crops) for k, m in models.items()}
    for row, a, b in zip(rows, ident["default"].assignments, ident["paper"].assignments,
                         strict=True):
        row["identified"] = {"default": a["predicted"] == a["label"],
                             "paper": b["predicted"] == b["label"]}
    elapsed = time.perf_counter() - t0

    def cells(fit: str, key: str) -> np.ndarray:
        return np.array([[r["speeds"][f"{s:g}"][fit][key] for s in TEST_MM_S] for r in rows])

    n = len(rows)
    print(f"\n{n} HaTT surfaces of {args.dir}, held-out strokes at "
          f"{', '.join(f'{s:g}' for s in TEST_MM_S)} mm/s ({elapsed:.0f} s)")
    print(f"{'fit':<10}{'mean LSD dB':>12}{'PSD corr':>10}{'identified':>12}")
    for fit in ("default", "paper", "ceiling"):
        ids = (f"{sum(r['identified'][fit] for r in rows)} / {n}" if fit != "ceiling"
               else "-")
        print(f"{fit:<10}{cells(fit, 'lsd_db').mean():12.2f}"
              f"{cells(fit, 'psd_correlation').mean():10.3f}{ids:>12}")
    print("per speed, mean LSD dB (15, 25, 35 lie between the training plateaus):")
    print(f"{'fit':<10}" + "".join(f"{s:>8g}" for s in TEST_MM_S))
    for fit in ("default", "paper", "ceiling"):
        print(f"{fit:<10}" + "".join(f"{x:8.2f}" for x in cells(fit, "lsd_db").mean(axis=0)))
    d, p = cells("default", "lsd_db"), cells("paper", "lsd_db")
    wins = {w: sum(r["winner"] == w for r in rows) for w in dict.fromkeys(r["winner"]
                                                                          for r in rows)}
    print(f"default better than paper in {int((d < p).sum())} of {d.size} cells; "
          f"validation chose {', '.join(f'{k} on {v}' for k, v in wins.items())}")
    print("surface                 winner      default  paper  ceiling  (mean LSD dB)")
    for r, dd, pp, cc in zip(rows, d, p, cells("ceiling", "lsd_db"), strict=True):
        print(f"{r['surface']:<24}{r['winner']:<10}{dd.mean():9.2f}{pp.mean():7.2f}"
              f"{cc.mean():9.2f}")
    if args.json:
        args.json.write_text(json.dumps({"surfaces": rows, "elapsed_s": elapsed}, indent=1,
                                        allow_nan=False) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
