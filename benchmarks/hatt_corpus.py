"""The texture fit on an independent corpus: surfaces rendered from Penn HaTT models.

    python benchmarks/hatt_corpus.py DIR --set tuning|report --work WORKDIR
        [--only "Book,Candle"] [--no-identify] [--json OUT.json]

DIR holds HaTT model files (``Models_<material>.xml``, Culbertson, Lopez Delgado and
Kuchenbecker 2014; not shipped: see the README). Per surface, through the project's HaTT
import (fydpad/texture/families/penn/toolkit.py), the toolkit's synthesis (fydpad/synth/hatt.py)
and :func:`texture_scans.penn_scan` (which adds a tool resonance, contact impacts, the hand's
wander and gravity on three axes):

- training: one 30 s hand stroke through plateaus near 10, 20, 30 and 40 mm/s;
- test: a 10 s stroke at about 15, 20, 25 and 35 mm/s (a separate rendering: held out),
  and a second rendering of each as the ceiling.

Fitted two ways on the training stroke: ``fydpad texture fit``'s default (validated
selection, fydpad/texture/lpc/select.py) and the paper's method read plainly (fit_paper).
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
from fydpad.synth.texture_scans import hand_speed, penn_scan, plateau_speed
from fydpad.texture.evaluation.evaluate import compare
from fydpad.texture.evaluation.identify import identify_families
from fydpad.texture.families.penn.toolkit import read_penn
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.family import LpcFamily
from fydpad.texture.lpc.fit import fit_paper
from fydpad.texture.lpc.model_file import load_model, save_model
from fydpad.texture.lpc.select import select_model
from fydpad.texture.lpc.synthesis import TextureRenderer
from fydpad.texture.scan_io import read_scan, write_scan

#: Free to look at and tune on (measured leaving one surface out: nothing is fitted
#: across surfaces, each surface's choice is made on its own training stroke).
TUNING = (
    "ABS Plastic", "Artificial Grass", "Binder", "Book", "Bubble Envelope", "Candle",
    "Canvas 3", "Cardboard", "Carpet 3", "Ceramic", "Cotton", "EPDM Foam", "Flannel",
    "Floortile 1", "Floortile 3", "Floortile 5", "Floortile 7", "Frosted Acrylic",
    "Glitter Paper", "Leather 1 Back", "Leather 2 Front", "Masking Tape", "Microfiber Cloth",
    "Nylon Bag", "Painted Brick", "Paper Bag", "Paper Plate 2", "Plastic Mesh 1",
    "Playing Card", "Polyethylene Foam", "Resin Carbon Fiber", "Sandpaper 220", "Scouring Pad",
    "Stained Wood", "Stone Tile 2", "Terra Cotta", "Textured Metal", "Tissue Paper", "Velvet",
    "Vinyl 2", "Wax Paper", "Whiteboard",
)
#: Run once when the work is done; never a reason to change the code.
REPORT = (
    "Aluminum Foil", "Athletic Shirt", "Blanket", "Brick 2", "CD Sleeve", "Canvas 2",
    "Carbon Fiber", "Carpet 2", "Carpet 4", "Coffee Filter", "Dot Paper", "File Portfolio",
    "Fleece", "Floortile 2", "Floortile 4", "Floortile 6", "Folder", "Gift Box",
    "Greeting Card", "Leather 2 Back", "MDF", "Metal Shelving", "Nitrile Glove", "Nylon Mesh",
    "Painted Wood", "Paper Plate 1", "Pink Foam", "Plastic Mesh 2", "Pleather",
    "Portfolio Cover", "Resume Paper", "Sandpaper Aluminum Oxide", "Silk 2", "Stone Tile 1",
    "Tarp", "Textured Cloth", "Textured Paper", "Velcro Loops", "Vinyl 1", "Wavy Acrylic",
    "Whiteboard Eraser",
)
#: The toolkit's other materials are kept for an independent check: not rendered.
SETS = {"tuning": TUNING, "report": REPORT}
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
    ap.add_argument("--set", choices=tuple(SETS), required=True,
                    help="tuning or report surfaces (the others in DIR are never opened)")
    ap.add_argument("--only", help="comma-separated material names within the set")
    ap.add_argument("--json", type=Path, help="write every figure as JSON")
    ap.add_argument("--work", type=Path, required=True,
                    help="where each surface's models, 20 mm/s held-out stroke and figures "
                    "(rows.jsonl) are kept as it is done; surfaces already there are not "
                    "rerun (a long run resumes, or is split over --only lists)")
    ap.add_argument("--no-identify", action="store_true",
                    help="skip the identification (a part of a split run)")
    args = ap.parse_args(argv)
    names = set(SETS[args.set])
    if args.only is not None:
        names &= {s.strip() for s in args.only.split(",")}
    # Filtered by file name before any file is opened.
    files = sorted(p for p in args.dir.glob("Models_*.xml") if p.stem[len("Models_"):] in names)
    if not files:
        print(f"{args.dir}: no Models_*.xml file of the {args.set} set"
              + (f" named {args.only}" if args.only else ""), file=sys.stderr)
        return 2
    rows, done = [], {}
    for sub in ("default", "paper", "held20"):
        (args.work / sub).mkdir(parents=True, exist_ok=True)
    rows_path = args.work / "rows.jsonl"
    if rows_path.exists():
        for line in rows_path.read_text().splitlines():
            r = json.loads(line)
            done[r["surface"]] = r
    t0 = time.perf_counter()
    warnings.simplefilter("ignore")  # clamping beyond the fitted speeds: said by fit/synth
    for path in progress(files, desc="surfaces", unit="surface"):
        name = path.stem[len("Models_"):]
        if name in done:
            rows.append(done[name])
            continue
        name, train, held, second = surface_scans(path)
        default, sel = select_model([train], speeds_mm_s=PLATEAUS_MM_S)
        paper = fit_paper([train])
        row = {"surface": name, "winner": sel.winner, "validated": sel.validated,
               "selection": sel.to_json(), "speeds": {}}
        d, p = score(default, held, second), score(paper, held, second)
        for s in TEST_MM_S:
            k = f"{s:g}"
            row["speeds"][k] = {"default": d[k][0], "paper": p[k][0], "ceiling": d[k][1]}
        save_model(default, args.work / "default" / f"{name}.json")
        save_model(paper, args.work / "paper" / f"{name}.json")
        h = held[20.0]
        n5 = round(5 * h.fs_hz)  # the first 5 s: N x N syntheses, kept short
        write_scan(args.work / "held20" / f"{name}.csv", h.t_s[:n5], h.acc[:n5],
                   h.speed_mm_s[:n5], meta={"surface": name})
        rows.append(row)
        with rows_path.open("a") as fh:
            fh.write(json.dumps(row, allow_nan=False) + "\n")
        print(f"{name}: chose {sel.winner}; mean LSD default "
              f"{np.mean([v['default']['lsd_db'] for v in row['speeds'].values()]):.2f} dB, "
              f"paper {np.mean([v['paper']['lsd_db'] for v in row['speeds'].values()]):.2f}, "
              f"ceiling {np.mean([v['ceiling']['lsd_db'] for v in row['speeds'].values()]):.2f}",
              flush=True)
    if not args.no_identify:
        # fydpad texture identify's library call on the files fit wrote.
        scans = [read_scan(args.work / "held20" / f"{r['surface']}.csv") for r in rows]
        for sc, r in zip(scans, rows, strict=True):  # a '# surface=' value ends at a space
            sc.meta["surface"] = r["surface"]
        for fit in ("default", "paper"):
            models = [LpcFamily(load_model(args.work / fit / f"{r['surface']}.json"))
                      for r in rows]
            ident = identify_families(models, [m.surface for m in models], scans,
                                      distance="bands")
            for r, a in zip(rows, ident.assignments, strict=True):
                r.setdefault("identified", {})[fit] = a["predicted"] == a["label"]
    elapsed = time.perf_counter() - t0

    def cells(fit: str, key: str) -> np.ndarray:
        return np.array([[r["speeds"][f"{s:g}"][fit][key] for s in TEST_MM_S] for r in rows])

    n = len(rows)
    print(f"\n{n} HaTT surfaces of {args.dir}, held-out strokes at "
          f"{', '.join(f'{s:g}' for s in TEST_MM_S)} mm/s ({elapsed:.0f} s)")
    print(f"{'fit':<10}{'mean LSD dB':>12}{'PSD corr':>10}{'identified':>12}")
    for fit in ("default", "paper", "ceiling"):
        ids = (f"{sum(r['identified'][fit] for r in rows)} / {n}"
               if fit != "ceiling" and not args.no_identify else "-")
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
    print(f"{'surface':<26}winner      default  paper  ceiling  (mean LSD dB)")
    for r, dd, pp, cc in zip(rows, d, p, cells("ceiling", "lsd_db"), strict=True):
        print(f"{r['surface']:<26}{r['winner']:<10}{dd.mean():9.2f}{pp.mean():7.2f}"
              f"{cc.mean():9.2f}")
    if args.json:
        args.json.write_text(json.dumps({"surfaces": rows, "elapsed_s": elapsed}, indent=1,
                                        allow_nan=False) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
