"""Which surface does each scan sound like (an objective analogue of Bianchi 2015's Table
I)? Every model of one family is rendered along each scan's own finger stream and the
scan goes to the model of nearest spectrum (Welch, 4 Hz bins, over the same samples):
``"bands"`` (LPC's default) the RMS level difference over third-octave bands, ``"lsd"`` the
log-spectral distance on the bins, ``"shape"`` (the other families') the dB difference less
its mean and tilt. docs/texture.md and docs/texture_families.md give the reasons."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.evaluation.evaluate import BAND_HZ, lsd_db, render_stroke, welch_psd
from fydpad.texture.families import get_kind
from fydpad.texture.families.friction import friction_coefficient
from fydpad.texture.family import TextureFamily
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]
BANDS_PER_OCTAVE = 3
#: (channel rendered, band compared in Hz, the scan's observable) unless a Kind says another.
DEFAULT_OBSERVABLE = ("vibration", BAND_HZ, "acceleration")


@dataclass
class Identification:
    labels: list[str]
    confusion: list[list[int]]  # [i][j]: scans of label i assigned to model label j
    rate: float
    assignments: list[dict]

    def to_json(self) -> dict:
        return {"rate": self.rate, "labels": self.labels, "confusion": self.confusion,
                "assignments": self.assignments}


def band_levels_db(f_hz: Array, p: Array, band_hz: tuple[float, float] = BAND_HZ,
                   per_octave: int = BANDS_PER_OCTAVE) -> Array:
    """Levels 10 log10(mean P) in fractional-octave bands with edges band[0] * 2^(k/n)
    (the last band ends at band[1]); bands holding no bin are left out."""
    k_max = int(np.ceil(per_octave * np.log2(band_hz[1] / band_hz[0]) - 1e-9))
    edges = band_hz[0] * 2.0 ** (np.arange(k_max + 1) / per_octave)
    edges[-1] = np.nextafter(band_hz[1], np.inf)
    levels = [10 * np.log10(np.mean(p[sel])) for lo, hi in pairwise(edges)
              if np.any(sel := (f_hz >= lo) & (f_hz < hi))]
    return np.asarray(levels)


def band_level_distance_db(f_hz: Array, p1: Array, p2: Array) -> float:
    """RMS over third-octave bands of the level difference in dB ("bands")."""
    d = band_levels_db(f_hz, p1) - band_levels_db(f_hz, p2)
    return float(np.sqrt(np.mean(d * d)))


def _bin_lsd_db(f_hz: Array, p1: Array, p2: Array) -> float:
    sel = (f_hz >= BAND_HZ[0]) & (f_hz <= BAND_HZ[1])
    return lsd_db(p1[sel], p2[sel])


DISTANCES: dict[str, Callable[[Array, Array, Array], float]] = {
    "bands": band_level_distance_db, "lsd": _bin_lsd_db}


def shape_distance_db(p1: Array, p2: Array, f: Array | None = None) -> float:
    """RMS of the dB difference of two spectra less its mean and, given the frequencies
    ``f``, its linear trend in log f."""
    d = 10 * np.log10(np.maximum(p1, 1e-30) / np.maximum(p2, 1e-30))
    if f is None:
        d = d - d.mean()
    else:
        lf = np.log(f)
        d = d - np.polyval(np.polyfit(lf, d, 1), lf)
    return float(np.sqrt(np.mean(d * d)))


def observe(scan: Scan, what: str, highpass_hz: float = 10.0) -> Array:
    """The scan's signal a family is compared with (the module docstring)."""
    if what == "friction":
        if scan.friction_n is None or scan.force_n is None:
            raise ValueError(f"{scan.path}: no friction_n/force_n columns")
        mu = friction_coefficient(scan.friction_n, scan.force_n)
        return np.nan_to_num(mu - np.nanmean(mu))
    return preprocess(scan.acc, scan.fs_hz, highpass_hz)


def identify_families(models: Sequence[TextureFamily], labels: Sequence[str],
                      scans: Sequence[Scan], *, seed: int = 0, distance: str = "shape",
                      wrap: Callable[[Iterable], Iterable] = lambda it: it,
                      model_names: Sequence[str] | None = None) -> Identification:
    """Assign each scan to the nearest model (all of one family, one per surface).

    ``"shape"`` is scored over each scan's moving samples, ``"bands"``/``"lsd"`` (the
    vibration against the acceleration high-passed as the family's fit) over the samples
    each model covers. Each scan's synthesis draws its noise from ``seed``, so a run is
    reproducible and independent of the order of the scans."""
    if distance != "shape" and distance not in DISTANCES:
        raise ValueError(f"distance {distance!r}: expected shape or one of "
                         f"{', '.join(DISTANCES)}")
    names = list(model_names) if model_names is not None else list(labels)
    channel, band, what = DEFAULT_OBSERVABLE
    if distance == "shape":
        channel, band, what = get_kind(models[0].kind).observable or DEFAULT_OBSERVABLE
    key = "shape_distance_db" if distance == "shape" else "distance_db"
    all_labels = list(dict.fromkeys([*labels, *(s.surface for s in scans)]))
    conf = np.zeros((len(all_labels), len(all_labels)), int)
    assignments = []
    for scan in wrap(scans):
        dists = []
        recorded: dict[tuple, tuple] = {}  # the scan's spectrum, once per high-pass and mask
        for m, name in zip(models, names, strict=True):
            mask = scan.speed_mm_s > 1.0  # every moving sample, or where enough, those
            if distance != "shape":  # the model covers (bands, lsd)
                covered = m.covers(scan.speed_mm_s)
                if covered.sum() >= scan.fs_hz / 2:
                    mask = covered
            key_psd = (m.highpass_hz, mask.tobytes())
            if key_psd not in recorded:
                try:
                    recorded[key_psd] = welch_psd(observe(scan, what, m.highpass_hz),
                                                  scan.fs_hz, mask)
                except ValueError as exc:  # the synthesis has the same mask: one check
                    raise UserError(f"{scan.path}: too short to identify ({scan.t_s.size} "
                                    f"rows, {int(mask.sum())} of them scanning by column "
                                    f"'speed_mm_s'): {exc}") from None
            f, pr = recorded[key_psd]
            syn = render_stroke(m, scan, channel, seed, name)
            if distance == "shape":
                _, ps = welch_psd(syn - np.mean(syn), scan.fs_hz, mask)
                sel = (f >= band[0]) & (f <= min(band[1], scan.fs_hz / 2))
                dists.append(shape_distance_db(pr[sel], ps[sel], f[sel]))
            else:
                _, ps = welch_psd(syn, scan.fs_hz, mask)
                dists.append(DISTANCES[distance](f, pr, ps))
        j = int(np.argmin(dists))
        conf[all_labels.index(scan.surface), all_labels.index(labels[j])] += 1
        assignments.append({"scan": scan.path, "label": scan.surface,
                            "predicted": labels[j], "distance": distance,
                            key: {lab: round(d, 3) for lab, d in
                                  zip(labels, dists, strict=True)}})
    rate = float(np.trace(conf) / max(1, conf.sum()))
    return Identification(all_labels, conf.tolist(), rate, assignments)


# --------------------------------------------------------------- the cross-family run
def by_surface(scans: Sequence[Scan]) -> dict[str, list[Scan]]:
    out: dict[str, list[Scan]] = {}
    for s in scans:
        out.setdefault(s.surface, []).append(s)
    return out


def fit_per_surface(kind: str, train: dict[str, list[Scan]], **options: Any
                    ) -> tuple[list[TextureFamily], list[str]]:
    """One model of ``kind`` per surface, fitted in memory with the fit ``options`` over
    the family's ``compare_options``."""
    k = get_kind(kind)
    models, labels = [], []
    for label, scans in train.items():
        quick = k.compare_options(scans) if k.compare_options is not None else {}
        opts = {**quick, **options}
        models.append(k.from_json(k.fit(scans, surface=label, **opts), f"{kind}:{label}"))
        labels.append(label)
    return models, labels


def compare_families(train: Sequence[Scan], test: Sequence[Scan], kinds: Sequence[str],
                     seed: int = 0) -> dict[str, tuple[Identification, dict] | str]:
    """Per family one model per training surface (label -> model), and every test scan
    identified; a family that cannot fit the scans gets the reason instead."""
    out: dict[str, tuple[Identification, dict] | str] = {}
    groups = by_surface(train)
    for kind in kinds:
        try:
            models, labels = fit_per_surface(kind, groups)
        except Exception as exc:  # a family that cannot fit these scans is reported
            out[kind] = f"not fitted: {exc}"
            continue
        out[kind] = (identify_families(models, labels, test, seed=seed),
                     dict(zip(labels, models, strict=True)))
    return out
