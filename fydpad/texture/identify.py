"""Objective analogue of the paper's Table I: which surface does each model sound like?

Every model is synthesized along each scan's own speed trace; the scan is assigned to
the model whose synthesized dB spectrum (Welch 4 Hz bins, 20-500 Hz) is nearest
(smallest log-spectral distance). confusion[i][j] counts scans of label i assigned
to model label j; the rate is the fraction on the diagonal.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import BAND_HZ, evaluation_mask, lsd_db, welch_psd
from fydpad.texture.model_file import TextureModel
from fydpad.texture.scan_io import Scan
from fydpad.texture.synthesis import TextureRenderer


@dataclass
class Identification:
    labels: list[str]
    confusion: list[list[int]]
    rate: float
    assignments: list[dict]

    def to_json(self) -> dict:
        return {"rate": self.rate, "labels": self.labels, "confusion": self.confusion,
                "assignments": self.assignments}


def identify(models: Sequence[TextureModel], scans: Sequence[Scan], *, method: str = "lsf",
             seed: int = 0, wrap: Callable[[Iterable], Iterable] = lambda it: it
             ) -> Identification:
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
            f, pr = welch_psd(rec, scan.fs_hz, mask)
            r.reset()
            r._rng = np.random.default_rng(seed)
            r.warmup(float(scan.speed_mm_s[0]), 0.5)
            syn = r.block(scan.speed_mm_s, True)
            _, ps = welch_psd(syn, scan.fs_hz, mask)
            sel = (f >= BAND_HZ[0]) & (f <= BAND_HZ[1])
            dists.append(lsd_db(pr[sel], ps[sel]))
        j = int(np.argmin(dists))
        conf[labels.index(scan.surface), labels.index(model_labels[j])] += 1
        assignments.append({"scan": scan.path, "label": scan.surface,
                            "predicted": model_labels[j],
                            "lsd_db": {lab: round(d, 3) for lab, d in
                                       zip(model_labels, dists, strict=True)}})
    rate = float(np.trace(conf) / max(1, conf.sum()))
    return Identification(labels, conf.tolist(), rate, assignments)


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
