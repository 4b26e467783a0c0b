"""The default fit's bias along speed, against the truth: the mean Welch spectrum of many
held-out strokes (docs/texture.md, "Speed coverage: where a model interpolates").

For each texture: two 10 s training strokes at each of 10, 20, 30 and 40 mm/s (seeds
TRAIN_SEED, TRAIN_SEED + 1), the default fit; at each speed, HELD held-out 12 s strokes
(seeds 100, 101, ...), each synthesized along its own speed trace with its own seed;
the bias is 10 log10(mean synthesized / mean recorded Welch PSD) over 20-500 Hz (4 Hz
bins), as an RMS in dB, and with ``--bands`` per band. Also the correlation of the
calibrated form's corrections log C_i at neighbouring fitted speeds (does a correction
carry across a gap?). ``--form two-part`` fits the two-part model alone (the calibrated
form's base, at its own 600 iterations); ``--set FIELD=VALUE`` changes a field of the
generator's textures for training and held-out strokes alike (``--set slip_mm=0``:
without stick-slip), to take a texture's processes apart. Minutes; prints, asserts
nothing.

    python benchmarks/texture_speed_bias.py [--textures all] [--speeds 10,15,...,40]
        [--train-seed 1] [--held 8] [--bands] [--form default|two-part] [--set F=V ...]
        [--load-scale 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import warnings

import numpy as np
from stroke_options import add_stroke_options, textures_and_speeds

from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import evaluation_mask, synthesize, welch_psd
from fydpad.texture.fit import fit_texture
from fydpad.texture.free_form import CalibratedSpectrum, spectrum_of
from fydpad.texture.scan_generator import TEXTURES, Texture, generate_scan

TRAIN_SPEEDS = (10.0, 20.0, 30.0, 40.0)
BAND_EDGES_HZ = (20, 30, 45, 60, 80, 100, 130, 160, 200, 250, 300, 400, 500)
WITHIN_DB = 0.6  # about what a held-out stroke tolerates within the target (docs)


def correction_correlations(spec: CalibratedSpectrum) -> list[float]:
    """Correlation over 20-500 Hz of log C_i and log C_i+1 (the fitted speeds')."""
    sel = (spec.f_hz >= 20) & (spec.f_hz <= 500)
    c = spec.log_c[:, sel]
    return [float(np.dot(a, b) / np.sqrt(np.dot(a, a) * np.dot(b, b)))
            for a, b in itertools.pairwise(c)]


def bias_db(texture: Texture, model, speed_mm_s: float, held: int, load_scale: float = 1.0
            ) -> tuple[float, np.ndarray, np.ndarray]:
    """(RMS bias over 20-500 Hz, f_hz, bias per bin) at one speed."""
    rec, syn = [], []
    for seed in range(100, 100 + held):
        scan = generate_scan(texture, speed_mm_s, 12.0, seed=seed, load_scale=load_scale)
        mask = evaluation_mask(scan, model)
        f, p = welch_psd(preprocess(scan.acc, scan.fs_hz), scan.fs_hz, mask)
        rec.append(p)
        syn.append(welch_psd(synthesize(model, scan.speed_mm_s, seed=seed), scan.fs_hz,
                             mask)[1])
    d = 10 * np.log10(np.mean(syn, axis=0) / np.mean(rec, axis=0))
    sel = (f >= 20) & (f <= 500)
    return float(np.sqrt(np.mean(d[sel] ** 2))), f, d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_stroke_options(ap, 8, "held-out strokes per speed")
    ap.add_argument("--bands", action="store_true", help="also the bias per band")
    ap.add_argument("--form", choices=("default", "two-part"), default="default",
                    help="the default fit, or the two-part model alone")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="a generator texture field for every stroke (repeatable)")
    args = ap.parse_args()
    names, speeds = textures_and_speeds(ap, args)
    changes = {}
    numeric = {f.name for f in dataclasses.fields(TEXTURES[names[0]])
               if f.type in ("float", float)}
    for item in args.set:
        field, eq, value = item.partition("=")
        if not eq or field not in numeric:
            ap.error(f"--set {item}: give FIELD=VALUE with FIELD one of the generator's "
                     f"numeric texture fields: {', '.join(sorted(numeric))}")
        try:
            changes[field] = float(value)
        except ValueError:
            ap.error(f"--set {item}: {value!r} is not a finite number")
        if not np.isfinite(changes[field]):
            ap.error(f"--set {item}: {value!r} is not a finite number")
    fit_options = {"two_part": True, "lines": "off"} if args.form == "two-part" else {}
    warnings.simplefilter("ignore")
    per_speed: dict[float, list[float]] = {v: [] for v in speeds}
    for name in names:
        texture = dataclasses.replace(TEXTURES[name], **changes)
        train = [generate_scan(texture, v, 10.0, seed=args.train_seed + j,
                               load_scale=args.load_scale)
                 for v in TRAIN_SPEEDS for j in range(2)]
        model, _ = fit_texture(train, **fit_options)
        if model.free_form is not None:
            spec = spectrum_of(model)
            if isinstance(spec, CalibratedSpectrum):
                cc = ", ".join(f"{c:+.2f}" for c in correction_correlations(spec))
                print(f"{name:15s} correlation of neighbouring corrections: {cc}")
        for v in speeds:
            rms, f, d = bias_db(texture, model, v, args.held, args.load_scale)
            per_speed[v].append(rms)
            print(f"{name:15s} {v:4g} mm/s  bias {rms:.2f} dB RMS", flush=True)
            if args.bands:
                bands = "  ".join(f"{lo}-{hi} {np.mean(d[(f >= lo) & (f < hi)]):+.1f}"
                                  for lo, hi in itertools.pairwise(BAND_EDGES_HZ))
                print(f"{'':15s} per band (Hz dB): {bands}")
    print(f"\n{len(names)} textures, train seed {args.train_seed}, {args.held} held-out "
          f"strokes per speed, {args.form} fit, load scale {args.load_scale:g}"
          + "".join(f", {k}={v:g}" for k, v in changes.items()) + ":")
    for v, r in per_speed.items():
        print(f"  {v:4g} mm/s: median {np.median(r):.2f} dB, mean {np.mean(r):.2f}, "
              f"within {WITHIN_DB} dB: {sum(x <= WITHIN_DB for x in r)}/{len(r)}")


if __name__ == "__main__":
    main()
