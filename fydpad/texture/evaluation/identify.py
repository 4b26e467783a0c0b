"""Which surface does each model sound like (an objective analogue of Bianchi 2015's
Table I)? Every model is rendered along each scan's own speed trace and the scan goes to
the model whose spectrum (Welch, 4 Hz bins, 20-500 Hz, over the same samples) is
nearest; confusion[i][j] counts scans of label i assigned to model label j.

Distances: ``"bands"`` (default), the RMS over third-octave bands (edges 20 * 2^(k/3)
Hz, 14 bands) of the level difference in dB, L_b = 10 log10(mean P over band b): weight
per octave, where a surface's content is (4 Hz bins put three quarters of the weight
above 140 Hz, mostly the sensor floor), and each band judged on its power rather than
on where a comb line sits to a bin; a third of an octave is also about the Weber
fraction of vibrotactile frequency discrimination. ``"lsd"``: the log-spectral distance
on the 4 Hz bins (evaluate's metric).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.evaluation.evaluate import BAND_HZ, evaluation_mask, lsd_db, welch_psd
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.interpolation import DEFAULT_METHOD
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.synthesis import TextureRenderer
from fydpad.texture.plots import pyplot
from fydpad.texture.scan_io import Scan


@dataclass
class Identification:
    labels: list[str]
    confusion: list[list[int]]
    rate: float
    assignments: list[dict]

    def to_json(self) -> dict:
        return {"rate": self.rate, "labels": self.labels, "confusion": self.confusion,
                "assignments": self.assignments}


Array = NDArray[np.float64]
BANDS_PER_OCTAVE = 3


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
    """RMS over third-octave bands of the level difference in dB (module docstring)."""
    d = band_levels_db(f_hz, p1) - band_levels_db(f_hz, p2)
    return float(np.sqrt(np.mean(d * d)))


def _bin_lsd_db(f_hz: Array, p1: Array, p2: Array) -> float:
    sel = (f_hz >= BAND_HZ[0]) & (f_hz <= BAND_HZ[1])
    return lsd_db(p1[sel], p2[sel])


DISTANCES: dict[str, Callable[[Array, Array, Array], float]] = {
    "bands": band_level_distance_db, "lsd": _bin_lsd_db}


def scored_samples(scan: Scan, covered: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The samples a model covers, or where too few (half a second), every moving one."""
    return covered if covered.sum() >= scan.fs_hz / 2 else scan.speed_mm_s > 1.0


def too_short(scan: Scan, mask: NDArray[np.bool_], exc: Exception) -> UserError:
    return UserError(f"{scan.path}: too short to identify ({scan.t_s.size} rows, "
                     f"{int(mask.sum())} of them scanning by column 'speed_mm_s'): {exc}")


def tally(model_labels: Sequence[str], scans: Sequence[Scan],
          distances: Callable[[Scan], list[float]], distance: str,
          wrap: Callable[[Iterable], Iterable], key: str = "distance_db") -> Identification:
    """Every scan assigned to the model of least ``distances(scan)`` (one per model)."""
    labels = list(dict.fromkeys(list(model_labels) + [s.surface for s in scans]))
    conf = np.zeros((len(labels), len(labels)), int)
    assignments = []
    for scan in wrap(scans):
        dists = distances(scan)
        j = int(np.argmin(dists))
        conf[labels.index(scan.surface), labels.index(model_labels[j])] += 1
        assignments.append({"scan": scan.path, "label": scan.surface,
                            "predicted": model_labels[j], "distance": distance,
                            key: {lab: round(d, 3) for lab, d in
                                  zip(model_labels, dists, strict=True)}})
    rate = float(np.trace(conf) / max(1, conf.sum()))
    return Identification(labels, conf.tolist(), rate, assignments)


def identify(models: Sequence[TextureModel], scans: Sequence[Scan], *, method: str = DEFAULT_METHOD,
             distance: str = "bands", seed: int = 0,
             wrap: Callable[[Iterable], Iterable] = lambda it: it,
             model_names: Sequence[str] | None = None) -> Identification:
    """Assign every scan to the LPC model with the nearest synthesized spectrum (one
    renderer per model, reseeded with ``seed`` for every scan). ``model_names`` (the
    model files) name the models in errors; a scan at another rate than a model, or too
    short for one spectrum, is a UserError naming the scan."""
    if distance not in DISTANCES:
        raise ValueError(f"distance {distance!r}: expected one of {', '.join(DISTANCES)}")
    names = list(model_names) if model_names is not None else [
        f"model '{m.surface}'" for m in models]
    for scan in scans:  # at another rate the synthesis's spectrum would be stretched
        for m, name in zip(models, names, strict=True):
            if abs(scan.fs_hz - m.fs_hz) > 1e-6 * m.fs_hz:
                raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz, "
                                f"{name}: key 'sample_rate_hz' {m.fs_hz:g} Hz")
    renderers = [TextureRenderer(m, method=method, ramp_s=1e-6) for m in models]

    def distances(scan: Scan) -> list[float]:
        out = []
        for m, r in zip(models, renderers, strict=True):
            mask = scored_samples(scan, evaluation_mask(scan, m))
            try:
                f, pr = welch_psd(preprocess(scan.acc, scan.fs_hz, m.highpass_hz),
                                  scan.fs_hz, mask)
            except ValueError as exc:  # the synthesis has the same mask: one check
                raise too_short(scan, mask, exc) from None
            r.reset()
            r.reseed(seed)  # each scan's synthesis independent of the scans before it
            r.warmup(float(scan.speed_mm_s[0]), 0.5)
            _, ps = welch_psd(r.block(scan.speed_mm_s, True), scan.fs_hz, mask)
            out.append(DISTANCES[distance](f, pr, ps))
        return out

    return tally([m.surface for m in models], scans, distances, distance, wrap)


def plot_confusion(path: str, ident: Identification, title: str = "") -> None:
    plt = pyplot()
    c = np.asarray(ident.confusion)
    n = len(ident.labels)
    fig, ax = plt.subplots(figsize=(1.0 + 0.5 * n, 1.0 + 0.45 * n), constrained_layout=True)
    ax.imshow(c, cmap="Blues")
    ax.set_xticks(range(n), ident.labels, rotation=60, ha="right")
    ax.set_yticks(range(n), ident.labels)
    ax.set_xlabel("identified as (model)")
    ax.set_ylabel("scan surface")
    for i in range(n):
        for j in range(n):
            if c[i, j]:
                ax.text(j, i, str(c[i, j]), ha="center", va="center")
    ax.set_title(title or f"identification rate {ident.rate:.0%}")
    fig.savefig(path, dpi=110)
    plt.close(fig)
