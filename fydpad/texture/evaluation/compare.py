"""Cross-family identification: one confusion matrix per family on the same scans.

Each family is compared on the signal it renders with that signal in the scan: the
``vibration`` along the scan's own finger stream against its DFT321 acceleration
(20-500 Hz), and friction's ``tension`` (affine in mu(x)) against the measured F_f / F_n
(2-100 Hz). The scan goes to the model of nearest spectral *shape*: the RMS of the dB
difference less its mean and linear trend in log frequency, since gains and what a
family models set levels and tilts (a grating renders a force, the scan holds an
acceleration: f^2 apart), while lines and bands identify a surface.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace

import numpy as np

from fydpad.errors import UserError
from fydpad.motors.base import MotorConfig
from fydpad.motors.drive import build_drive
from fydpad.motors.sim import indenter_press
from fydpad.softness import SPECIMENS, fit_through_origin
from fydpad.texture.evaluation.evaluate import BAND_HZ, welch_psd
from fydpad.texture.evaluation.identify import (
    DISTANCES,
    Identification,
    scored_samples,
    tally,
    too_short,
)
from fydpad.texture.families import get_kind
from fydpad.texture.families.friction import friction_coefficient
from fydpad.texture.family import RateMismatch, finger_from_scan
from fydpad.texture.lpc.dft321 import preprocess

#: Per family: (the channel rendered, the band compared in Hz, the scan's observable).
OBSERVABLES = {"friction": ("tension", (2.0, 100.0), "friction")}
DEFAULT_OBSERVABLE = ("vibration", BAND_HZ, "acceleration")


def shape_distance_db(p1: np.ndarray, p2: np.ndarray, f: np.ndarray | None = None) -> float:
    """RMS of the dB difference of two spectra after removing its mean and, given the
    frequencies ``f``, its linear trend in log f (shape only)."""
    d = 10 * np.log10(np.maximum(p1, 1e-30) / np.maximum(p2, 1e-30))
    if f is None:
        d = d - d.mean()
    else:
        lf = np.log(f)
        d = d - np.polyval(np.polyfit(lf, d, 1), lf)
    return float(np.sqrt(np.mean(d * d)))


def observe(scan, what: str, highpass_hz: float = 10.0) -> np.ndarray:
    """The scan's signal a family is compared with (see the module docstring)."""
    if what == "friction":
        if scan.friction_n is None or scan.force_n is None:
            raise ValueError(f"{scan.path}: no friction_n/force_n columns")
        mu = friction_coefficient(scan.friction_n, scan.force_n)
        return np.nan_to_num(mu - np.nanmean(mu))
    return preprocess(scan.acc, scan.fs_hz, highpass_hz)


def identify_families(models: Sequence, labels: Sequence[str], scans: Sequence, *,
                      seed: int = 0, distance: str = "shape",
                      wrap: Callable[[Iterable], Iterable] = lambda it: it,
                      model_names: Sequence[str] | None = None) -> Identification:
    """Assign each scan to the nearest model (all of one family, one per surface).

    ``distance``: "shape" (the module docstring; over each scan's moving samples) or
    :mod:`~fydpad.texture.evaluation.identify`'s "bands"/"lsd" (the vibration against the
    acceleration high-passed as the family's fit, over the samples each model covers).
    A family with a ``seed`` parameter (LPC, HaTT) draws its noise from ``seed`` for
    every scan, so a run is reproducible."""
    if distance != "shape" and distance not in DISTANCES:
        raise ValueError(f"distance {distance!r}: expected shape or one of "
                         f"{', '.join(DISTANCES)}")
    where = list(model_names) if model_names is not None else list(labels)
    channel, band, what = (OBSERVABLES.get(models[0].kind, DEFAULT_OBSERVABLE)
                           if distance == "shape" else DEFAULT_OBSERVABLE)

    def distances(scan) -> list[float]:
        finger = finger_from_scan(scan)
        dists = []
        for m, name in zip(models, where, strict=True):
            mask = scan.speed_mm_s > 1.0
            if distance != "shape":
                mask = scored_samples(scan, m.covers(scan.speed_mm_s))
            try:
                f, pr = welch_psd(observe(scan, what, m.highpass_hz), scan.fs_hz, mask)
            except ValueError as exc:
                raise too_short(scan, mask, exc) from None
            if "seed" in m.parameters:
                m.set_parameter("seed", seed)
            m.reset()
            try:
                syn = m.render(finger, channel)
            except RateMismatch as exc:
                raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz, "
                                f"{name}: {exc}") from None
            except ValueError as exc:
                raise UserError(f"{scan.path}: {name}: {exc}") from None
            if distance == "shape":
                _, ps = welch_psd(syn - np.mean(syn), scan.fs_hz, mask)
                sel = (f >= band[0]) & (f <= min(band[1], scan.fs_hz / 2))
                dists.append(shape_distance_db(pr[sel], ps[sel], f[sel]))
            else:
                _, ps = welch_psd(syn, scan.fs_hz, mask)
                dists.append(DISTANCES[distance](f, pr, ps))
        return dists

    key = "shape_distance_db" if distance == "shape" else "distance_db"
    return tally(labels, scans, distances, distance, wrap, key)


# --------------------------------------------------------------- the cross-family run
def by_surface(scans: Sequence) -> dict[str, list]:
    out: dict[str, list] = {}
    for s in scans:
        out.setdefault(s.surface, []).append(s)
    return out


def fit_per_surface(kind: str, train: dict[str, list], **options) -> tuple[list, list[str]]:
    """One model of ``kind`` per surface (fitted in memory, as ``fit --kind`` would)."""
    k = get_kind(kind)
    models, labels = [], []
    for label, scans in train.items():
        opts = dict(options.get(kind, {}))
        if kind == "lpc":
            opts.setdefault("order", 60)
            opts.setdefault("speeds_mm_s", sorted({round(float(np.median(s.speed_mm_s)) / 5)
                                                   * 5.0 for s in scans}))
        data = k.fit(scans, surface=label, **opts)
        models.append(k.from_json(data, f"{kind}:{label}"))
        labels.append(label)
    return models, labels


def compare_families(train: Sequence, test: Sequence, kinds: Sequence[str], seed: int = 0
                     ) -> dict[str, Identification | str]:
    """Per family one model per training surface, and every test scan identified."""
    out: dict[str, Identification | str] = {}
    groups = by_surface(train)
    for kind in kinds:
        try:
            models, labels = fit_per_surface(kind, groups)
        except Exception as exc:  # a family that cannot fit these scans is reported
            out[kind] = f"not fitted: {exc}"
            continue
        out[kind] = identify_families(models, labels, test, seed=seed)
    return out


# --------------------------------------------------------------- Bianchi 2015 Table I
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


def specimen_experiment(kind: str, train: dict[str, list], test: dict[str, list],
                        reference: dict[str, list], trials: int = 3, seed: int = 0) -> dict:
    """Bianchi 2015's 2 x 2 (S1/S2 x R1/R2, specimens SS1..SS4) with the pad simulated:
    each trial renders a specimen's roughness by the family's model of R1 or R2 along a
    test stroke and its softness on the simulated motors, measured by an indenter press.
    The identifier knows the specimens' roughness scans (``reference``) and stiffness
    (Table I); spectra alone cannot separate SS1 from SS3 (both R1), spectra and
    stiffness (each distance scaled by its spread over the specimens) can."""
    names = sorted(SPECIMENS)
    rough = {n: "R1" if abs(SPECIMENS[n].period_mm - 3.90) < 0.01 else "R2" for n in names}
    models, labels = fit_per_surface(kind, {r: train[r] for r in ("R1", "R2")})
    fam = dict(zip(labels, models, strict=True))
    channel, band, what = OBSERVABLES.get(kind, DEFAULT_OBSERVABLE)
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
                m = fam[r]
                if "seed" in m.parameters:  # the same seed, the same confusion matrix
                    m.set_parameter("seed", seed + k)
                m.reset()
                syn = m.render(finger_from_scan(stroke), channel)
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
