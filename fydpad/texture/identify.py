"""Objective analogue of the paper's Table I: which surface does each model sound like?

Every model is synthesized along each scan's own speed trace (the renderer follows the
scan's speed, as it would follow a finger); the scan is assigned to the model whose
synthesized dB spectrum (Welch 4 Hz bins, 20-500 Hz, over the same samples) is nearest.
confusion[i][j] counts scans of label i assigned to model label j; the rate is the
fraction on the diagonal.

Distances (``distance=``):

- ``"bands"`` (default): the band-level distance. Each spectrum is reduced to its levels
  in third-octave bands (edges 20 * 2^(k/3) Hz, 14 bands over 20-500 Hz),
  L_b = 10 log10(mean of P over the band's bins), and the distance is the RMS over the
  bands of L_rec,b - L_syn,b in dB. Why, two reasons, both measured (docs/texture.md):
  (1) weight per octave, not per hertz: 4 Hz bins over 20-500 Hz put three quarters of
  the weight above 140 Hz, where most textures are the sensor floor and where the
  models' steep edges sit a few bins off between modelled speeds (the generator's
  sandpaper_p80 at 15 mm/s: a 40 dB cliff at 190-220 Hz that its model, interpolated
  between 10 and 20 mm/s, puts 30 dB high at 220-260 Hz, so its own model scored worse
  than brick's, wrong by 5-15 dB below 200 Hz); third-octave bands put 7 of 14 bands
  below 100 Hz, where a surface's content is. (2) Within a band the model is judged on
  its power, not on where each comb line sits to a 4 Hz bin (mesh_steel: odd
  harmonics of v / 0.6 mm that wander with the hand). A third of an octave (26 %) is
  also about the Weber fraction of vibrotactile frequency discrimination; the paper's
  Table I is a human's identification.
- ``"lsd"``: the log-spectral distance on the 4 Hz bins, sqrt(mean d^2) with
  d = 10 log10(P_rec / P_syn) (evaluate's metric; the distance used before).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.evaluate import BAND_HZ, evaluation_mask, lsd_db, welch_psd
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.interpolation import DEFAULT_METHOD
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.synthesis import TextureRenderer
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


def identify(models: Sequence[TextureModel], scans: Sequence[Scan], *, method: str = DEFAULT_METHOD,
             distance: str = "bands", seed: int = 0,
             wrap: Callable[[Iterable], Iterable] = lambda it: it,
             model_names: Sequence[str] | None = None) -> Identification:
    """Assign every scan to the model with the nearest synthesized spectrum (``distance``:
    ``"bands"`` or ``"lsd"``, module docstring). ``model_names`` (the model files) name
    the models in errors; a scan at another rate than a model, or too short for one
    spectrum, is a UserError naming the scan."""
    if distance not in DISTANCES:
        raise ValueError(f"distance {distance!r}: expected one of {', '.join(DISTANCES)}")
    names = list(model_names) if model_names is not None else [
        f"model '{m.surface}'" for m in models]
    _check_rates(models, names, scans)
    dist_fn = DISTANCES[distance]
    model_labels = [m.surface for m in models]
    labels = list(dict.fromkeys(model_labels + [s.surface for s in scans]))
    conf = np.zeros((len(labels), len(labels)), int)
    assignments = []
    renderers = [TextureRenderer(m, method=method, ramp_s=1e-6) for m in models]
    for scan in wrap(scans):
        dists = []
        for m, r in zip(models, renderers, strict=True):
            mask = evaluation_mask(scan, m)
            if mask.sum() < scan.fs_hz / 2:
                mask = scan.speed_mm_s > 1.0
            rec = preprocess(scan.acc, scan.fs_hz, m.highpass_hz)
            try:
                f, pr = welch_psd(rec, scan.fs_hz, mask)
            except ValueError as exc:  # the synthesis has the same mask: one check
                raise UserError(f"{scan.path}: too short to identify ({scan.t_s.size} rows, "
                                f"{int(mask.sum())} of them scanning by column "
                                f"'speed_mm_s'): {exc}") from None
            r.reset()
            r.reseed(seed)  # each scan's synthesis independent of the scans before it
            r.warmup(float(scan.speed_mm_s[0]), 0.5)
            syn = r.block(scan.speed_mm_s, True)
            _, ps = welch_psd(syn, scan.fs_hz, mask)
            dists.append(dist_fn(f, pr, ps))
        j = int(np.argmin(dists))
        conf[labels.index(scan.surface), labels.index(model_labels[j])] += 1
        assignments.append({"scan": scan.path, "label": scan.surface,
                            "predicted": model_labels[j],
                            "distance": distance,
                            "distance_db": {lab: round(d, 3) for lab, d in
                                            zip(model_labels, dists, strict=True)}})
    rate = float(np.trace(conf) / max(1, conf.sum()))
    return Identification(labels, conf.tolist(), rate, assignments)


def _check_rates(models: Sequence[TextureModel], names: Sequence[str],
                 scans: Sequence[Scan]) -> None:
    """The synthesis runs at the model's rate along the scan's samples: at another rate
    its spectrum is stretched (a 2 kHz model on 1 kHz scans: an octave down), so the
    scores would mean nothing; evaluate_scan refuses it the same way."""
    for scan in scans:
        for m, name in zip(models, names, strict=True):
            if abs(scan.fs_hz - m.fs_hz) > 1e-6 * m.fs_hz:
                raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz, "
                                f"{name}: key 'sample_rate_hz' {m.fs_hz:g} Hz")


def plot_confusion(path: str, ident: Identification, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
