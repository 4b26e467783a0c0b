"""Fig. 10-like figures: recorded against model spectra (matplotlib Agg)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray


def plot_spectra(path: str | Path, panels: Sequence[tuple[str, NDArray, NDArray, NDArray]],
                 title: str = "", band: tuple[float, float] = (20.0, 500.0)) -> Path:
    """One panel per (label, f_hz, P_recorded, P_model), dB re 1 (m/s^2)^2/Hz."""
    n = max(1, len(panels))
    cols = min(2, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(6 * cols, 3 * rows), squeeze=False,
                             constrained_layout=True)
    for ax, (label, f, pr, pm) in zip(axes.flat, panels, strict=False):
        sel = (f >= band[0]) & (f <= band[1])
        ax.plot(f[sel], 10 * np.log10(pr[sel]), label="recorded (DFT321)")
        ax.plot(f[sel], 10 * np.log10(pm[sel]), label="model", alpha=0.85)
        ax.set_title(label)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("PSD [dB (m/s²)²/Hz]")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    axes.flat[0].legend()
    if title:
        fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
