"""Texture figures: recorded against model spectra (Bianchi 2015 Fig. 10), the ceiling,
the confusion matrix. matplotlib loads only when a figure is drawn (the families' modules
import this one, and the station's render process never draws)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from fydpad.texture.evaluation.evaluate import BAND_HZ
from fydpad.texture.lpc.coverage import MIN_SECONDS_PER_BIN

if TYPE_CHECKING:
    from matplotlib.axes import Axes

PSD_LABEL = "PSD (dB re (m/s²)²/Hz)"


@dataclass
class SpeedCoverage:
    """The coverage panel: coverage.speed_histogram's (edges, seconds of steady scan),
    the fitted speeds and the gaps (mm/s)."""

    edges_mm_s: NDArray
    seconds: NDArray
    fitted_mm_s: Sequence[float]
    gaps_mm_s: Sequence[tuple[float, float]]


def plot_spectra(path: str | Path, panels: Sequence[tuple[str, NDArray, NDArray, NDArray]],
                 title: str = "", coverage: SpeedCoverage | None = None) -> Path:
    """One panel per (label, f_hz, P_recorded, P_model); with ``coverage``, a last panel
    of the scans' time per speed bin, the fitted speeds and the gaps."""
    # Here, not at the top: matplotlib loads only when a figure is drawn.
    from fydpad.plots import label, plt, save_figure

    n = max(1, len(panels))
    cols = min(2, n)
    rows = (n + cols - 1) // cols
    extra = 1 if coverage is not None else 0
    fig = plt.figure(figsize=(6 * cols, 3 * (rows + extra)), constrained_layout=True)
    grid = fig.add_gridspec(rows + extra, cols)
    axes = [fig.add_subplot(grid[i // cols, i % cols]) for i in range(rows * cols)]
    for ax, (name, f, pr, pm) in zip(axes, panels, strict=False):
        sel = (f >= BAND_HZ[0]) & (f <= BAND_HZ[1])
        ax.plot(f[sel], 10 * np.log10(pr[sel]), label="recorded (DFT321)")
        ax.plot(f[sel], 10 * np.log10(pm[sel]), label="model", alpha=0.85)
        ax.set_title(name)
        ax.set_xlabel(label("frequency", "Hz"))
        ax.set_ylabel(PSD_LABEL)
        ax.grid(alpha=0.3)
    for ax in axes[len(panels):]:
        ax.axis("off")
    axes[0].legend()
    if coverage is not None:
        _plot_coverage(fig.add_subplot(grid[rows, :]), coverage)
    return save_figure(fig, path, title)


def _plot_coverage(ax: Axes, cov: SpeedCoverage) -> None:
    # Here, not at the top: matplotlib loads only when a figure is drawn.
    from fydpad.plots import label

    e = np.asarray(cov.edges_mm_s, float)
    ax.bar(e[:-1], cov.seconds, width=np.diff(e), align="edge", color="tab:blue",
           alpha=0.7, label="scans (s per bin)")
    for i, (lo, hi) in enumerate(cov.gaps_mm_s):
        ax.axvspan(lo, hi, color="tab:red", alpha=0.15,
                   label="no scan: interpolated" if i == 0 else None)
    ax.axhline(MIN_SECONDS_PER_BIN, color="tab:blue", lw=0.8, ls=":",
               label=f"{MIN_SECONDS_PER_BIN:g} s: counts as scanned")
    for i, v in enumerate(cov.fitted_mm_s):
        ax.axvline(v, color="k", lw=1, ls="--", label="fitted speeds" if i == 0 else None)
    used = np.flatnonzero(np.asarray(cov.seconds) > 0)
    if used.size:
        ax.set_xlim(max(e[used[0]] - 2.0, 0.0), e[used[-1] + 1] + 2.0)
    ax.set_xlabel(label("speed", "mm/s"))
    ax.set_ylabel(label("scan time", "s"))
    ax.set_title("speed coverage")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")


def plot_against_ceiling(path: str | Path, f_hz: NDArray, recorded: NDArray, model: NDArray,
                         second: NDArray, title: str = "") -> Path:
    """``evaluate --second``: the three spectra, and below them the model's and the
    second recording's difference to the recording in dB."""
    # Here, not at the top: matplotlib loads only when a figure is drawn.
    from fydpad.plots import label, legend_outside, plt, save_figure

    sel = (f_hz >= BAND_HZ[0]) & (f_hz <= BAND_HZ[1])
    f = f_hz[sel]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True,
                                      constrained_layout=True,
                                      gridspec_kw={"height_ratios": [2, 1]})
    top.plot(f, 10 * np.log10(recorded[sel]), label="recorded (DFT321)")
    top.plot(f, 10 * np.log10(model[sel]), label="model", alpha=0.85)
    top.plot(f, 10 * np.log10(second[sel]), color="0.5", lw=0.8, label="second recording")
    top.set_ylabel(PSD_LABEL)
    bottom.axhline(0.0, color="k", lw=0.6)
    bottom.plot(f, 10 * np.log10(model[sel] / recorded[sel]), color="tab:orange",
                label="model − recorded")
    bottom.plot(f, 10 * np.log10(second[sel] / recorded[sel]), color="0.5", lw=0.8,
                label="second − recorded (the ceiling)")
    bottom.set_ylabel(label("difference", "dB"))
    bottom.set_xlabel(label("frequency", "Hz"))
    for ax in (top, bottom):
        legend_outside(ax)
        ax.grid(alpha=0.3)
    return save_figure(fig, path, title)


def plot_confusion(path: str, ident: Any, title: str = "") -> None:
    """An identification's confusion matrix (``evaluation.identify.Identification``):
    scans by surface against the model each was assigned to."""
    # Here, not at the top: matplotlib loads only when a figure is drawn.
    from fydpad.plots import plt, save_figure

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
    save_figure(fig, path)
