"""Issue 7's held-out figures taken apart (docs/texture.md, "causes per texture" and
"Identification: third-octave band levels"). Minutes each; prints, asserts nothing.

    python benchmarks/texture_causes.py modelled [SPEED] [TEXTURES]   # default 30 mm/s, all
    python benchmarks/texture_causes.py between [TEXTURES]            # 25 mm/s, R1,R2
    python benchmarks/texture_causes.py identify TRAIN_SEED HELD_SEED SPEEDS [TRAIN_S HELD_S]
    python benchmarks/texture_causes.py lengths SPEED LENGTHS [HELD_SEED SECOND_SEED]
    python benchmarks/texture_causes.py protocol SPEED HELD_S NxSECONDS HELD_SEED SECOND_SEED \
        TRAIN_SEED [TEXTURES]
    python benchmarks/texture_causes.py methods TRAIN_SEED HELD_SEED SECOND_SEED
    python benchmarks/texture_causes.py forms SPEEDS HELD_SEED SECOND_SEED TRAIN_SEED \
        [NxSECONDS HELD_S [TEXTURES [FORMS]]]
    python benchmarks/texture_causes.py constant TEXTURE [TRAIN_SEED]

``modelled``: test_targets.py's former 14-texture set-up (one 5 s training stroke per speed,
held-out 4 s stroke seed 50, ceiling seed 51), the gap (LSD - ceiling) and correlation
of the default fit, of 3x the data, of the two-part model and of both.
``between``: test_targets.py's figures set-up (8 s strokes) at 25 mm/s, two-part: the
ceiling over four second recordings, and the bias of 4 synthesized realisations per
40 Hz band, and the gap when every table entry's all-pole filter is replaced by the
minimum-phase FIR of S itself (cepstrum; no all-pole fit). ``identify``: rate and
closest call with both distances (bands, lsd).
``lengths``: the ceiling (a second recording scored against the held-out stroke) for
held-out strokes of each length: how long a stroke must be for the target to be
reachable. ``protocol``: the test protocol of ``test_targets.py``'s every_texture
set-up (N training strokes of SECONDS per speed, seeds TRAIN_SEED...; held-out stroke
of HELD_S): gap and correlation of the pooled fit, the two-part model, the form
chosen by two-fold cross-validation on the training strokes (``choose``), and the
paper's plain method (linear interpolation of the pooled fit's coefficients).
``methods``: the pooled fit (two 10 s strokes per speed) rendered by "stretch" or by the
paper's linear way, chosen per texture by two-fold cross-validation on the training
strokes, scored on 12 s held-out strokes at 30 and 25 mm/s.
``forms``: the spectral forms side by side on one seed set (default two 10 s training
strokes per speed, 12 s held-out strokes, all textures): ``default`` (what ``fit`` fits
now: a periodic surface's lines, the calibrated spectrum for the others; ask for it in
FORMS), the pooled fit ("stretch"), the two-part model, the paper's linear
interpolation of the pooled fit, the calibrated two-part model (``fit --free-form``), and
on request (FORMS, comma-separated) ``free``, ``surface`` (free_form.py's other forms)
and ``hold5`` (the pooled fit held over the whole +-5 mm/s of each fitted speed: what the
paper's linear way approximates near a fitted speed), and ``third``: a third recording
(seed SECOND_SEED + 1) scored in the model's place, what a perfect replica of the
surface that is itself a recording meets. Gap (LSD - ceiling) / correlation,
``*`` where both targets are met, the fit time, and the met count per form and speed.
``constant``: how well the speed-resolved spectra (two-part, calibrated; fitted on two
10 s strokes per speed from TRAIN_SEED, default 8) match the texture's spectrum at a
*constant* speed (strokes without the hand's wander, 12 s, at 26-34 mm/s): correlation
and LSD of S (with the render's +-1 mm/s average) against the Welch spectrum, beside a
second constant-speed stroke.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import (
    compare,
    compare_recordings,
    evaluate_scan,
    evaluation_mask,
    welch_psd,
)
from fydpad.texture.fit import fit_texture as _fit_texture
from fydpad.texture.identify import identify
from fydpad.texture.lpc import energy_length
from fydpad.texture.scan_generator import TEXTURES, generate_scan
from fydpad.texture.speed_warp import NFFT
from fydpad.texture.synthesis import TextureRenderer, synthesize
from fydpad.texture.two_part import RENDER_SMEAR_MM_S, TwoPartSpectrum

SPEEDS = (10.0, 20.0, 30.0, 40.0)


def fit_texture(*args, lines="off", **kwargs):
    """The forms here are the whole signal's (the figures of docs/texture.md before the
    lines); the ``default`` form of ``forms`` asks for the lines."""
    return _fit_texture(*args, lines=lines, **kwargs)


def modelled(speed: float, names: list[str]) -> None:
    for n in names:
        t1 = [generate_scan(n, s, 5.0, seed=1) for s in SPEEDS]
        t3 = t1 + [generate_scan(n, s, 5.0, seed=k) for s in SPEEDS for k in (2, 3)]
        held = generate_scan(n, speed, 4.0, seed=50)
        second = generate_scan(n, speed, 4.0, seed=51)
        base = fit_texture(t1, free_form=None)[0]
        mask = evaluation_mask(held, base)
        ceil = compare_recordings(held, second, base, mask)
        row = []
        for label, model in (("pooled", base), ("3x data", fit_texture(t3, free_form=None)[0]),
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
        syn = _render_exact_s(model, held.speed_mm_s)
        exact = compare(rec, syn, 1000.0, mask)[0]
        bands = " ".join(f"{lo}:{np.mean(d[(f >= lo) & (f < lo + 40)]):+.1f}"
                         for lo in range(20, 500, 40))
        print(f"{n}: ceilings {np.round(ceils, 2)}; gap {c.lsd_db - ceils[0]:+.2f} (seed 200), "
              f"{c.lsd_db - np.mean(ceils):+.2f} (mean); corr {c.psd_correlation:.3f}; "
              f"exact-S FIR: gap {exact.lsd_db - ceils[0]:+.2f}, corr {exact.psd_correlation:.3f}\n"
              f"  mean of 4 syntheses minus recording, dB per 40 Hz band from: {bands}",
              flush=True)


def _render_exact_s(model, speed_mm_s, seed: int = 0):
    """The renderer with each table entry's FIR set to the minimum-phase response of
    sqrt(S(f, v)) (averaged over v +- RENDER_SMEAR_MM_S, as TwoPartSpectrum.ar does):
    S rendered without an all-pole fit."""
    tp = TwoPartSpectrum.from_json(model.two_part)
    r = TextureRenderer(model, method="stretch", seed=seed, ramp_s=1e-6)
    f = np.arange(NFFT // 2 + 1) * model.fs_hz / NFFT
    rows = []
    for v in r.table.speeds_mm_s:
        p = np.mean([tp.psd(float(u)) for u in v + RENDER_SMEAR_MM_S * np.linspace(-1, 1, 5)],
                    axis=0)
        c = np.fft.irfft(0.5 * np.interp(f, tp.f_hz, np.log(np.maximum(p, 1e-300))), NFFT)
        c[1:NFFT // 2] *= 2.0  # fold the cepstrum: minimum phase
        c[NFFT // 2 + 1:] = 0.0
        rows.append(np.fft.irfft(np.exp(np.fft.rfft(c)), NFFT)[:4096])
    fir = np.array(rows)
    n = min(max(energy_length(fir, 1e-4), 16), 4096)
    r._use_fir(fir[:, :n])  # the responses and every state built on them
    r.warmup(float(speed_mm_s[0]), 0.5)
    return r.block(speed_mm_s, True, speed_mm_s.size)


def identification(train_seed: int, held_seed: int, speeds: list[float],
                   train_s: float = 5.0, held_s: float = 4.0) -> None:
    models = [fit_texture([generate_scan(n, s, train_s, seed=train_seed) for s in SPEEDS],
                          free_form=None)[0]
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


def lengths(speed: float, seconds: list[float], held_seed: int = 50,
            second_seed: int = 51) -> None:
    ref = fit_texture([generate_scan("R1", s, 5.0, seed=1) for s in SPEEDS],
                      free_form=None)[0]  # its mask only
    for n in TEXTURES:
        row = []
        for length in seconds:
            h = generate_scan(n, speed, length, seed=held_seed)
            s = generate_scan(n, speed, length, seed=second_seed)
            mask = evaluation_mask(h, ref) & evaluation_mask(s, ref)
            c = compare_recordings(h, s, ref, mask)
            row.append(f"{length:g} s {c.psd_correlation:.3f}/{c.lsd_db:.2f}")
        print(f"{n:15s} " + "  ".join(row), flush=True)


def _score(model, scans, seed: int = 0) -> list[float]:
    """LSD of ``model`` on each scan as evaluate_scan scores it, one renderer for all."""
    r = TextureRenderer(model, method="stretch", seed=seed, ramp_s=1e-6)
    out = []
    for scan in scans:
        mask = evaluation_mask(scan, model)
        r.reset()
        r.reseed(seed)
        r.warmup(float(scan.speed_mm_s[0]), 0.5)
        syn = r.block(scan.speed_mm_s, True, scan.speed_mm_s.size)
        out.append(compare(preprocess(scan.acc, 1000.0), syn, 1000.0, mask)[0].lsd_db)
    return out


def choose(train: list, n_per_speed: int) -> tuple[str, float, float]:
    """Pooled or two-part by two-fold cross-validation on the training strokes only:
    each speed's strokes alternate between the folds; each form is fitted on one fold
    and scored (LSD) on the other's strokes; the lower mean wins."""
    fold = [k % 2 for k in range(len(train))] if n_per_speed > 1 else None
    if fold is None:
        raise SystemExit("choose needs at least two strokes per speed")
    lsd = {}
    for form in ("pooled", "two-part"):
        got = []
        for k in (0, 1):
            fit_on = [s for s, f in zip(train, fold, strict=True) if f != k]
            test = [s for s, f in zip(train, fold, strict=True) if f == k]
            got += _score(fit_texture(fit_on, two_part=form == "two-part", free_form=None)[0],
                              test)
        lsd[form] = float(np.mean(got))
    return min(lsd, key=lsd.get), lsd["pooled"], lsd["two-part"]


def protocol(speed: float, held_s: float, train: str, held_seed: int, second_seed: int,
             train_seed: int, names: list[str]) -> None:
    k, train_s = int(train.split("x")[0]), float(train.split("x")[1])
    met: dict[str, list[str]] = {"pooled": [], "two-part": [], "chosen": [],
                                 "paper linear": []}
    for n in names:
        t = [generate_scan(n, s, train_s, seed=train_seed + j) for s in SPEEDS for j in range(k)]
        models = {"pooled": fit_texture(t, free_form=None)[0],
                  "two-part": fit_texture(t, two_part=True)[0]}
        form, cv_p, cv_t = choose(t, k) if k > 1 else ("pooled", np.nan, np.nan)
        models["chosen"] = models[form]
        held = generate_scan(n, speed, held_s, seed=held_seed)
        second = generate_scan(n, speed, held_s, seed=second_seed)
        mask = evaluation_mask(held, models["pooled"])
        ceil = compare_recordings(held, second, models["pooled"], mask)
        row = []
        for label, model in [*models.items(), ("paper linear", models["pooled"])]:
            how = "linear" if label == "paper linear" else "stretch"
            c, _ = evaluate_scan(model, held, method=how, mask=mask)
            ok = c.psd_correlation >= 0.95 and c.lsd_db <= ceil.lsd_db + 0.25
            met[label] += [n] if ok else []
            row.append(f"{label} {c.lsd_db - ceil.lsd_db:+.2f}/{c.psd_correlation:.3f}"
                       + ("*" if ok else " "))
        print(f"{n:15s} ceiling {ceil.lsd_db:.2f}/{ceil.psd_correlation:.3f}  " + "  ".join(row)
              + f"  (cv: {form}, {cv_p:.2f}/{cv_t:.2f} dB)", flush=True)
    for label, got in met.items():
        print(f"{label}: met {len(got)}/{len(names)} {got}")


def methods(train_seed: int, held_seed: int, second_seed: int) -> None:
    met = {"stretch": 0, "linear": 0, "chosen": 0}
    for n in TEXTURES:
        t = [generate_scan(n, s, 10.0, seed=train_seed + j) for s in SPEEDS for j in (0, 1)]
        cv = {}
        for how in ("stretch", "linear"):
            got = []
            for k in (0, 1):
                m = fit_texture(t[1 - k::2], free_form=None)[0]
                r = TextureRenderer(m, method=how, seed=0, ramp_s=1e-6)
                for sc in t[k::2]:
                    r.reset()
                    r.reseed(0)
                    r.warmup(float(sc.speed_mm_s[0]), 0.5)
                    syn = r.block(sc.speed_mm_s, True, sc.speed_mm_s.size)
                    got.append(compare(preprocess(sc.acc, 1000.0), syn, 1000.0,
                                       evaluation_mask(sc, m))[0].lsd_db)
            cv[how] = float(np.mean(got))
        chosen = min(cv, key=cv.get)
        model = fit_texture(t, free_form=None)[0]
        row = []
        for v in (30.0, 25.0):
            h = generate_scan(n, v, 12.0, seed=held_seed)
            s = generate_scan(n, v, 12.0, seed=second_seed)
            mask = evaluation_mask(h, model)
            ce = compare_recordings(h, s, model, mask)
            for how in ("stretch", "linear"):
                c = evaluate_scan(model, h, method=how, mask=mask)[0]
                ok = c.psd_correlation >= 0.95 and c.lsd_db <= ce.lsd_db + 0.25
                if v == 30.0:
                    met[how] += ok
                    met["chosen"] += ok and how == chosen
                row.append(f"{v:g} {how} {c.lsd_db - ce.lsd_db:+.2f}/{c.psd_correlation:.3f}"
                           + ("*" if ok else " "))
        print(f"{n:15s} cv stretch {cv['stretch']:.2f} linear {cv['linear']:.2f} -> "
              f"{chosen:8s}" + "  ".join(row), flush=True)
    print("met at 30 mm/s:", met)


FORM_FIT = {"default": {"lines": "auto"}, "pooled": {"free_form": None},
            "two-part": {"two_part": True},
            "linear": {"free_form": None},
            "calibrated": {"free_form": "calibrated"}, "free": {"free_form": "free"},
            "surface": {"free_form": "surface"}, "hold5": {"free_form": None}}


def _evaluate(model, held, mask, form: str):
    """evaluate_scan by the form's method; ``hold5``: "stretch" with every fitted model
    held over +-5 mm/s (the renderer's table built with hold_mm_s=5)."""
    if form != "hold5":
        return evaluate_scan(model, held, method="linear" if form == "linear" else "stretch",
                             mask=mask)[0]
    import fydpad.texture.synthesis as synthesis

    build = synthesis.build_table
    synthesis.build_table = lambda m, method, step: build(m, method, step, hold_mm_s=5.0)
    try:
        return evaluate_scan(model, held, method="stretch", mask=mask)[0]
    finally:
        synthesis.build_table = build


def forms(speeds: list[float], held_seed: int, second_seed: int, train_seed: int,
          train: str = "2x10", held_s: float = 12.0, names: list[str] | None = None,
          which: list[str] | None = None) -> None:
    import time

    k, train_s = int(train.split("x")[0]), float(train.split("x")[1])
    which = which or ["pooled", "two-part", "linear", "calibrated"]
    if all(f == "third" for f in which):
        raise SystemExit("forms: 'third' needs a model form beside it (its evaluation "
                         "mask is the model's), e.g. default,third")
    met = {(f, v): [] for f in which for v in speeds}
    for n in names or list(TEXTURES):
        t = [generate_scan(n, s, train_s, seed=train_seed + j) for s in SPEEDS for j in range(k)]
        models, cost = {}, {}
        for f in which:
            if f == "third":
                continue
            same = "pooled" if f in ("linear", "hold5") and "pooled" in models else None
            t0 = time.process_time()
            models[f] = models[same] if same else fit_texture(t, **FORM_FIT[f])[0]
            cost[f] = time.process_time() - t0
        ref = next(iter(models.values()))
        for v in speeds:
            held = generate_scan(n, v, held_s, seed=held_seed)
            second = generate_scan(n, v, held_s, seed=second_seed)
            mask = evaluation_mask(held, ref)
            ceil = compare_recordings(held, second, ref, mask)
            row = []
            for f in which:
                if f == "third":  # a third recording in the model's place
                    third = generate_scan(n, v, held_s, seed=second_seed + 1)
                    c = compare_recordings(held, third, ref, mask)
                else:
                    c = _evaluate(models[f], held, mask, f)
                ok = c.psd_correlation >= 0.95 and c.lsd_db <= ceil.lsd_db + 0.25
                met[(f, v)] += [n] if ok else []
                row.append(f"{f} {c.lsd_db - ceil.lsd_db:+.2f}/{c.psd_correlation:.3f}"
                           + ("*" if ok else " "))
            print(f"{n:15s} {v:g} ceiling {ceil.lsd_db:.2f}/{ceil.psd_correlation:.3f}  "
                  + "  ".join(row), flush=True)
        print("  fit s: " + ", ".join(f"{f} {c:.2f}" for f, c in cost.items()), flush=True)
    for (f, v), got in met.items():
        print(f"{f} at {v:g} mm/s: met {len(got)}/{len(names or TEXTURES)} {got}")


def constant(name: str, train_seed: int = 8) -> None:
    from fydpad.texture.evaluate import lsd_db, psd_correlation
    from fydpad.texture.free_form import spectrum_of

    t = [generate_scan(name, s, 10.0, seed=train_seed + j) for s in SPEEDS for j in (0, 1)]
    cal = fit_texture(t, free_form="calibrated")[0]
    specs = {"two-part": TwoPartSpectrum.from_json(cal.two_part), "calibrated": spectrum_of(cal)}
    smear = RENDER_SMEAR_MM_S * np.linspace(-1.0, 1.0, 5)

    def welch_at(v: float, seed: int):
        sc = generate_scan(name, v, 12.0, seed=seed, hand_variation=0.0)
        return welch_psd(preprocess(sc.acc, 1000.0)[500:-500], 1000.0)

    for v in (26.0, 28.0, 30.0, 32.0, 34.0):
        f, p = welch_at(v, 3)
        _, p2 = welch_at(v, 4)
        sel = (f >= 20) & (f <= 500)

        def score(q, p=p, sel=sel) -> str:
            return f"{psd_correlation(p[sel], q[sel]):.3f}/{lsd_db(p[sel], q[sel]):.2f}"

        row = [f"second stroke {score(p2)}"]
        for label, sp in specs.items():
            # S is power per 2 Hz bin (mean = power); the Welch density is 2 S / fs.
            e = np.interp(f, sp.f_hz, np.mean([sp.psd(v + d) for d in smear], axis=0)) * 2e-3
            row.append(f"{label} {score(e)}")
        print(f"{name} at {v:g} mm/s (corr/LSD dB): " + "  ".join(row), flush=True)


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
    elif what == "lengths":
        lengths(float(args[0]), [float(v) for v in args[1].split(",")],
                *(int(a) for a in args[2:4]))
    elif what == "protocol":
        protocol(float(args[0]), float(args[1]), args[2], int(args[3]), int(args[4]),
                 int(args[5]), args[6].split(",") if len(args) > 6 else list(TEXTURES))
    elif what == "methods":
        methods(*(int(a) for a in args[:3]))
    elif what == "constant":
        constant(args[0], *(int(a) for a in args[1:2]))
    elif what == "forms":
        forms([float(v) for v in args[0].split(",")], int(args[1]), int(args[2]), int(args[3]),
              *(args[4:5] or ["2x10"]), *([float(args[5])] if len(args) > 5 else []),
              *([args[6].split(",")] if len(args) > 6 and args[6] != "all" else
                ([None] if len(args) > 6 else [])),
              *([args[7].split(",")] if len(args) > 7 else []))
    else:
        raise SystemExit(__doc__)
