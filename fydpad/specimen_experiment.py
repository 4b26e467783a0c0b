"""Bianchi 2015's Table I simulated: the four specimens SS1..SS4 (softness S1/S2 x
roughness R1/R2), each rendered as the pad does (roughness by a texture family along a
stroke, softness on the simulated motors and fabric, measured by an indenter press) and
identified by spectra alone and by spectra plus the pressed stiffness
(``fydpad texture compare --specimens``; docs/texture_families.md)."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from fydpad.errors import UserError
from fydpad.motors.base import MotorConfig
from fydpad.motors.drive import build_drive
from fydpad.motors.sim import indenter_press
from fydpad.softness import SPECIMENS, fit_through_origin
from fydpad.texture.evaluation.evaluate import render_stroke, welch_psd
from fydpad.texture.evaluation.identify import (
    DEFAULT_OBSERVABLE,
    Identification,
    by_surface,
    observe,
    shape_distance_db,
)
from fydpad.texture.families import get_kind
from fydpad.texture.family import TextureFamily
from fydpad.texture.plots import plot_confusion
from fydpad.texture.scan_io import Scan


def press_stiffness(drive, k_n_per_mm: float, rng: np.random.Generator) -> float:
    """``k_n_per_mm`` rendered on the simulated fabric and measured as the paper's
    indenter does: presses of 0.5-10 mm (noisy force and depth), F = k delta fitted."""
    drive.set_stiffness(k_n_per_mm)

    def hold(ticks: int = 5) -> None:
        for _ in range(ticks):
            drive.tick(0.0)

    hold(600)
    d, f = indenter_press(drive.motors.plant, np.linspace(0.5, 10.0, 12), rng, hold=hold)
    return fit_through_origin(d, f).k_n_per_mm


def specimen_experiment(kind: str, models: dict[str, TextureFamily], test: dict[str, list],
                        reference: dict[str, list], trials: int = 3, seed: int = 0) -> dict:
    """Each trial renders a specimen's roughness by the family's model of R1 or R2
    (``models``) along a test stroke and presses its softness. The identifier knows the
    specimens' roughness scans (``reference``) and stiffness (Table I); spectra alone
    cannot separate SS1 from SS3 (both R1), spectra and stiffness (each distance scaled by
    its spread over the specimens) can."""
    names = sorted(SPECIMENS)
    rough = {n: "R1" if abs(SPECIMENS[n].period_mm - 3.90) < 0.01 else "R2" for n in names}
    channel, band, what = get_kind(kind).observable or DEFAULT_OBSERVABLE
    ref_psd = {}
    for r in ("R1", "R2"):
        ps = []
        for sc in reference[r]:
            f, p = welch_psd(observe(sc, what), sc.fs_hz, sc.speed_mm_s > 1)
            ps.append(p)
        ref_psd[r] = np.mean(ps, axis=0)
    sel = (f >= band[0]) & (f <= band[1])
    drive = build_drive(replace(MotorConfig(), backend="sim"))  # its softness table
    drive.start()
    rng = np.random.default_rng(seed)
    conf = {"spectra": np.zeros((4, 4), int), "spectra+stiffness": np.zeros((4, 4), int)}
    rows = []
    try:
        for n in names:
            for k in range(trials):
                r = rough[n]
                stroke = test[r][k % len(test[r])]
                # The same seed, the same confusion matrix.
                syn = render_stroke(models[r], stroke, channel, seed + k)
                _, ps = welch_psd(syn - syn.mean(), stroke.fs_hz, stroke.speed_mm_s > 1)
                d_spec = np.array([shape_distance_db(ref_psd[rough[j]][sel], ps[sel], f[sel])
                                   for j in names])
                k_hat = press_stiffness(drive, SPECIMENS[n].lambda_n_per_mm, rng)
                d_k = np.array([abs(np.log(k_hat / SPECIMENS[j].lambda_n_per_mm))
                                for j in names])
                i = names.index(n)
                conf["spectra"][i, int(np.argmin(d_spec))] += 1
                spread_s = np.ptp(d_spec) or 1.0
                spread_k = np.ptp([np.log(SPECIMENS[j].lambda_n_per_mm) for j in names])
                both = d_spec / spread_s + d_k / spread_k
                conf["spectra+stiffness"][i, int(np.argmin(both))] += 1
                rows.append({"specimen": n, "trial": k, "k_measured_n_per_mm": round(k_hat, 4),
                             "spectral_distance_db": dict(zip(names, np.round(d_spec, 3)
                                                              .tolist(), strict=True))})
    finally:
        drive.safe_stop()
    return {
        "kind": kind, "specimens": names, "trials": trials,
        "rate": {key: float(np.trace(c) / c.sum()) for key, c in conf.items()},
        "confusion": {key: c.tolist() for key, c in conf.items()}, "rows": rows,
    }


def check_specimen_scans(train: list[Scan], test: list[Scan]) -> dict[str, list[Scan]]:
    """The test scans by surface; a UserError, before any fit, unless both the training
    and the test scans hold R1 and R2."""
    tr, te = by_surface(train), by_surface(test)
    if not all(r in tr and r in te for r in ("R1", "R2")):
        raise UserError("--specimens: the --train and --scans need R1 and R2 scans "
                        "(fydpad texture generate-scans --textures R1,R2)")
    return te


def specimens_command(fitted: dict[str, dict[str, TextureFamily]], test: dict[str, list[Scan]],
                      out_dir: Path, trials: int = 3) -> tuple[dict, list[str]]:
    """``compare --specimens``: per family (``fitted``: kind -> surface -> model, as
    ``texture compare`` fitted them) the 2 x 2, its lines to print and its confusion plots
    in ``out_dir``."""
    result, lines = {}, []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind, models in fitted.items():
            r = result[kind] = specimen_experiment(kind, models, test, test, trials=trials)
            lines.append(f"{kind:9s} SS1..SS4: spectra alone {r['rate']['spectra']:.0%}, "
                         f"with the stiffness of a press {r['rate']['spectra+stiffness']:.0%}")
            for key, conf in r["confusion"].items():
                rate = r["rate"][key]
                plot_confusion(str(out_dir / f"specimens_{kind}_{key.replace('+', '_')}.png"),
                               Identification(r["specimens"], conf, rate, []),
                               f"{kind}, {key}: {rate:.0%}")
    return result, lines
