"""``fydpad texture``: fit, synthesize, evaluate and identify LPC texture models."""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from pathlib import Path

import numpy as np

from fydpad.errors import UserError
from fydpad.progress import progress
from vision.recording import CsvRowWriter, RecordingError


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}"
                                         ) from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "texture", help="texture models: fit from scans, synthesize, evaluate, identify",
        description=(
            "Speed-indexed LPC texture models (paper section III-B): fit them from texture "
            "scan recordings (RECORDING_FORMAT.md), synthesize eq. 5 at 1 kHz, compare "
            "synthesized with recorded spectra, and identify surfaces from their models. "
            "See docs/texture.md."),
    )
    tsub = p.add_subparsers(dest="texture_command", metavar="SUBCOMMAND", required=True)

    f = tsub.add_parser(
        "fit", help="fit a model file from scans of one surface",
        description=(
            "Fit one texture model file from one or more scans of the same surface. Each "
            "scan's three axes are high-passed at --highpass-hz (hand motion, gravity), "
            "reduced to one signal by DFT321, cut into runs whose speed stays within "
            "--tolerance of each target speed, and an LPC model of --order is fitted per "
            "speed up to Nyquist (autocorrelation/Levinson-Durbin or Burg). Every model's "
            "stability is checked. The 165-220 Hz band of the paper is stored as the "
            "output drive filter, not used for fitting."),
    )
    f.add_argument("scans", nargs="+", metavar="SCAN.csv", help="texture scan recordings")
    f.add_argument("--out", required=True, metavar="MODEL.json", help="model file to write")
    f.add_argument("--order", type=int, default=200, help="LPC order per speed (default 200)")
    f.add_argument("--speeds", type=_floats, default=[10.0, 20.0, 30.0, 40.0],
                   metavar="S1,S2,..", help="target speeds in mm/s (default 10,20,30,40)")
    f.add_argument("--tolerance", type=float, default=5.0, metavar="MM_S",
                   help="a run is valid while |speed - target| <= this (default 5 mm/s)")
    f.add_argument("--min-seconds", type=float, default=0.25,
                   help="shortest run used (default 0.25 s)")
    f.add_argument("--highpass-hz", type=float, default=10.0,
                   help="high-pass removing the tool's motion (default 10 Hz)")
    f.add_argument("--method", choices=("autocorrelation", "burg"), default="autocorrelation",
                   help="LPC estimator (default autocorrelation)")
    f.add_argument("--prewhiten-order", type=int, default=8, metavar="Q",
                   help="order of the first, spectrum-flattening LPC stage (default 8; 0 for "
                   "a one-stage fit); the model's total order stays --order")
    f.add_argument("--surface", help="surface label (default: the scans' # surface= or name)")
    f.add_argument("--drive-band", type=_floats, default=[165.0, 220.0], metavar="LO,HI",
                   help="output drive filter band stored in the model (default 165,220 Hz)")
    f.add_argument("--plot", metavar="FIG.png",
                   help="recorded against model spectra per speed (like the paper's Fig. 10)")
    f.set_defaults(func=run_fit)

    s = tsub.add_parser(
        "synth", help="synthesize a model at a speed to t_s,a CSV",
        description=(
            "Synthesize a(k) = e(k) + h^T a(k-1) (eq. 5) at the model's rate (1 kHz) for a "
            "constant finger speed and write t_s,a (m/s^2). Below the slowest model the "
            "output fades out with speed; above the fastest it is clamped (with a warning)."),
    )
    s.add_argument("model", metavar="MODEL.json", help="model file from 'fydpad texture fit'")
    s.add_argument("--speed-mm-s", type=float, required=True, help="finger speed in mm/s")
    s.add_argument("--seconds", type=float, required=True, help="duration in seconds")
    s.add_argument("--out", required=True, metavar="OUT.csv", help="CSV t_s,a to write")
    s.add_argument("--method", choices=("lsf", "reflection", "linear"), default="lsf",
                   help="interpolation between speeds (lsf default; linear is the paper's)")
    s.add_argument("--drive-filter", action="store_true",
                   help="apply the model's drive band filter (e.g. 165-220 Hz) to the output")
    s.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    s.set_defaults(func=run_synth)

    e = tsub.add_parser(
        "evaluate", help="compare a model's synthesis with a recorded scan",
        description=(
            "Synthesize the model along the scan's own speed trace and compare it with the "
            "scan's DFT321 signal (high-passed, before any drive filter), where the speed is "
            "within the model's range: power-spectrum correlation over 20-500 Hz (Welch, "
            "4 Hz bins; the paper's 'correlation in frequency'), log-spectral distance in "
            "dB, band energies, and the paper's time correlation (expected near 0: two "
            "realisations of a random process do not correlate sample by sample)."),
    )
    e.add_argument("model", metavar="MODEL.json", help="model file from 'fydpad texture fit'")
    e.add_argument("scan", metavar="SCAN.csv", help="a texture scan recording to compare with")
    e.add_argument("--json", metavar="OUT.json", help="write the figures as JSON")
    e.add_argument("--plot", metavar="FIG.png", help="recorded against synthesized spectra")
    e.add_argument("--method", choices=("lsf", "reflection", "linear"), default="lsf",
                   help="interpolation between speeds (lsf default; linear is the paper's)")
    e.add_argument("--seed", type=int, default=0, help="noise seed of the synthesis (default 0)")
    e.set_defaults(func=run_evaluate)

    i = tsub.add_parser(
        "identify", help="match scans to models (confusion matrix)",
        description=(
            "An objective analogue of the paper's Table I: synthesize every model along each "
            "scan's speed trace and assign the scan to the model with the nearest spectrum "
            "(log-spectral distance, 20-500 Hz). A scan's label is its '# surface=' metadata, "
            "else its file name; a model's label is the surface it was fitted on. Prints "
            "the rate; --json writes {rate, labels, confusion, assignments}."),
    )
    i.add_argument("models", nargs="+", metavar="MODEL.json", help="one model file per surface")
    i.add_argument("--scans", nargs="+", required=True, metavar="SCAN.csv",
                   help="scans to identify (labels from '# surface=' or the file name)")
    i.add_argument("--json", metavar="OUT.json",
                   help="write {rate, labels, confusion, assignments}")
    i.add_argument("--plot", metavar="FIG.png", help="the confusion matrix")
    i.add_argument("--method", choices=("lsf", "reflection", "linear"), default="lsf",
                   help="interpolation between speeds (lsf default; linear is the paper's)")
    i.set_defaults(func=run_identify)

    g = tsub.add_parser(
        "generate-scans", help="write synthetic scans (a physical generator, not AR)",
        description=(
            "Write synthetic texture scans: a tool dragged by a hand over a surface profile "
            "with impacts, stick-slip, a tool resonance, sensor noise, hand motion and "
            "gravity. Includes the paper's gratings R1 (3.90 mm) and R2 (2.15 mm). Files are "
            "named SURFACE_SPEEDmms_sSEED.csv. Deterministic per seed."),
    )
    g.add_argument("--out-dir", required=True, metavar="DIR")
    g.add_argument("--textures", default="all",
                   help="comma-separated names or 'all' (--list shows them)")
    g.add_argument("--speeds", type=_floats, default=[10.0, 20.0, 30.0, 40.0], metavar="S,..")
    g.add_argument("--strokes", type=int, default=2, help="strokes per texture and speed")
    g.add_argument("--seconds", type=float, default=8.0, help="stroke length (default 8 s)")
    g.add_argument("--seed", type=int, default=1, help="first stroke seed (default 1)")
    g.add_argument("--list", action="store_true", help="list the textures and exit")
    g.set_defaults(func=run_generate)


def _load_scans(paths: list[str]) -> list:
    from fydpad.texture.scan_io import read_scan

    try:
        return [read_scan(p) for p in paths]
    except RecordingError as exc:
        raise UserError(str(exc)) from None


def _load_model(path: str):
    from fydpad.texture.model_file import load_model

    return load_model(path)


def run_fit(args: argparse.Namespace) -> int:
    from fydpad.texture.dft321 import preprocess
    from fydpad.texture.evaluate import welch_psd
    from fydpad.texture.fit import fit_texture
    from fydpad.texture.lpc import ar_psd
    from fydpad.texture.model_file import save_model
    from fydpad.texture.segment import segment_by_speed

    if args.order < 1:
        raise UserError("--order must be at least 1")
    if len(args.drive_band) != 2:
        raise UserError("--drive-band needs LO,HI")
    scans = _load_scans(args.scans)
    model, reports = fit_texture(
        scans, order=args.order, speeds_mm_s=args.speeds, tolerance_mm_s=args.tolerance,
        highpass_hz=args.highpass_hz, min_seconds=args.min_seconds, method=args.method,
        surface=args.surface, drive_band_hz=tuple(args.drive_band),
        prewhiten_order=args.prewhiten_order,
        wrap=lambda it: progress(it, total=len(scans), desc="fit"))
    save_model(model, args.out)
    g2 = 9.80665**2
    print(f"{args.out}: surface {model.surface}, order {model.order}, {model.fs_hz:g} Hz")
    for r in reports:
        print(f"  {r.speed_mm_s:5.1f} mm/s: {r.n_samples} samples in {r.n_segments} runs, "
              f"sigma2 {r.sigma2:.3g} (m/s^2)^2 = {r.sigma2 / g2:.3g} g^2, "
              f"prediction gain {10 * math.log10(r.signal_var / r.sigma2):.1f} dB, stable")
    if args.plot:
        from fydpad.texture.plots import plot_spectra

        panels = []
        for k, s in enumerate(model.speeds_mm_s):
            segs = []
            for sc in scans:
                x = preprocess(sc.acc, sc.fs_hz, model.highpass_hz)
                rs = segment_by_speed(sc.speed_mm_s, sc.fs_hz, [s], args.tolerance)[float(s)]
                mask = np.zeros(x.size, bool)
                for a, b in rs:
                    mask[a:b] = True
                segs.append((x, mask))
            x = np.concatenate([a for a, _ in segs])
            m = np.concatenate([b for _, b in segs])
            fr, pr = welch_psd(x, model.fs_hz, m)
            panels.append((f"{s:g} mm/s", fr, pr, ar_psd(model.poly(k), model.sigma2[k], fr,
                                                           model.fs_hz)))
        plot_spectra(args.plot, panels, f"{model.surface}: recorded vs LPC model")
    return 0


def run_synth(args: argparse.Namespace) -> int:
    from fydpad.texture.synthesis import TextureRenderer

    model = _load_model(args.model)
    if not args.seconds > 0 or not math.isfinite(args.seconds):
        raise UserError("--seconds must be positive")
    if not args.speed_mm_s >= 0:
        raise UserError("--speed-mm-s must be >= 0")
    n = round(args.seconds * model.fs_hz)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = TextureRenderer(model, method=args.method, seed=args.seed,
                            drive_filter=args.drive_filter)
        r.warmup(args.speed_mm_s, 0.5)
        r._g = r.target_gain(args.speed_mm_s, True)
        a = r.block(args.speed_mm_s, True, n)
    for w in caught:
        print(f"fydpad texture synth: warning: {args.model}: {w.message}", file=sys.stderr)
    with CsvRowWriter(args.out, ("t_s", "a"), comment=f"surface={model.surface} "
                      f"speed_mm_s={args.speed_mm_s:g} method={args.method}") as wr:
        for k, v in enumerate(a):
            wr.write(k / model.fs_hz, float(v))
    print(f"{args.out}: {n} samples, rms {float(np.sqrt(np.mean(a * a))):.4g} m/s^2")
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    from fydpad.texture.evaluate import evaluate_scan, evaluation_mask

    model = _load_model(args.model)
    scan = _load_scans([args.scan])[0]
    mask = evaluation_mask(scan, model)
    if mask.sum() < model.fs_hz / 4 * 2:
        raise UserError(
            f"{args.scan}: column 'speed_mm_s': too little of the scan "
            f"({mask.sum()} samples) is within the model's speeds "
            f"{model.speeds_mm_s[0]:g}-{model.speeds_mm_s[-1]:g} mm/s")
    try:
        c, extra = evaluate_scan(model, scan, method=args.method, seed=args.seed, mask=mask)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    out = {"model": args.model, "scan": args.scan, "method": args.method, **c.to_json(),
           "note": "time_correlation compares independent realisations: ~0 expected"}
    print(f"power-spectrum correlation (20-500 Hz): {c.psd_correlation:.3f} "
          f"(dB spectra {c.psd_correlation_db:.3f}); log-spectral distance {c.lsd_db:.2f} dB; "
          f"time correlation {c.time_correlation:.3f} (independent realisations: ~0 expected)")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    if args.plot:
        from fydpad.texture.plots import plot_spectra

        plot_spectra(args.plot, [(f"{scan.surface} vs {model.surface}", extra["f_hz"],
                                  extra["recorded"], extra["synthesized"])],
                     f"corr {c.psd_correlation:.3f}, LSD {c.lsd_db:.2f} dB")
    return 0


def run_identify(args: argparse.Namespace) -> int:
    from fydpad.texture.identify import identify, plot_confusion

    models = [_load_model(p) for p in args.models]
    scans = _load_scans(args.scans)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = identify(models, scans, method=args.method,
                         wrap=lambda it: progress(it, total=len(scans), desc="identify"))
    print(f"identification rate {ident.rate:.1%} ({len(scans)} scans, {len(models)} models)")
    if args.json:
        Path(args.json).write_text(json.dumps(ident.to_json(), indent=1) + "\n",
                                   encoding="utf-8")
    if args.plot:
        plot_confusion(args.plot, ident)
    return 0


def run_generate(args: argparse.Namespace) -> int:
    from fydpad.texture.scan_generator import TEXTURES, generate_scan, save_generated

    if args.list:
        for t in TEXTURES.values():
            print(f"{t.name:16s} period {t.period_mm:g} mm, resonance {t.resonance_hz:g} Hz")
        return 0
    names = list(TEXTURES) if args.textures == "all" else [
        n.strip() for n in args.textures.split(",") if n.strip()]
    unknown = [n for n in names if n not in TEXTURES]
    if unknown:
        raise UserError(f"--textures: unknown {', '.join(unknown)} (known: {', '.join(TEXTURES)})")
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(n, s, args.seed + k) for n in names for s in args.speeds for k in range(args.strokes)]
    for n, s, seed in progress(jobs, total=len(jobs), desc="generate"):
        scan = generate_scan(n, s, args.seconds, seed=seed)
        save_generated(scan, out / f"{n}_{s:g}mms_s{seed}.csv")
    print(f"{out}: {len(jobs)} scans")
    return 0
