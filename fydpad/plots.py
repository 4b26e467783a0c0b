"""Plots a person would rather look at than read (matplotlib, no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike


def plot_track(
    path: str | Path,
    t_s: ArrayLike,
    x_mm: ArrayLike,
    y_mm: ArrayLike,
    indentation_mm: ArrayLike | None = None,
    workspace_mm: tuple[float, float] = (100.0, 70.0),
    truth: dict[str, ArrayLike] | None = None,
    title: str = "",
) -> Path:
    """The track over time (x, y, indentation) and on the workspace seen from above."""
    t = np.asarray(t_s, float)
    x = np.asarray(x_mm, float)
    y = np.asarray(y_mm, float)
    ind = None if indentation_mm is None else np.asarray(indentation_mm, float)
    has_ind = ind is not None and np.isfinite(ind).any()
    rows = 3 if has_ind else 2
    fig = plt.figure(figsize=(12, 2.4 * rows + 0.6), constrained_layout=True)
    grid = fig.add_gridspec(rows, 2, width_ratios=(1.6, 1))
    series = [("x_mm", x, "x [mm]"), ("y_mm", y, "y [mm]")]
    if has_ind:
        series.append(("indentation_mm", ind, "indentation [mm]"))
    axes = []
    for i, (key, values, label) in enumerate(series):
        ax = fig.add_subplot(grid[i, 0], sharex=axes[0] if axes else None)
        if truth is not None and key in truth:
            ax.plot(truth["t_s"], truth[key], color="0.6", lw=2.5, label="truth")
        ax.plot(t, values, color="C0", lw=1.0, label="tracked")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        axes.append(ax)
    axes[-1].set_xlabel("t [s]")
    axes[0].legend(loc="upper right", fontsize=8)
    ax = fig.add_subplot(grid[:, 1])
    w, h = workspace_mm
    ax.add_patch(plt.Rectangle((-w / 2, -h / 2), w, h, fill=False, color="0.3"))
    if truth is not None:
        ax.plot(truth["x_mm"], truth["y_mm"], color="0.6", lw=2.5, label="truth")
    sc = ax.scatter(x, y, c=t, s=6, cmap="viridis", label="tracked")
    fig.colorbar(sc, ax=ax, label="t [s]", shrink=0.7)
    ax.set_xlim(-w / 2 - 5, w / 2 + 5)
    ax.set_ylim(-h / 2 - 5, h / 2 + 5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm] (user's right)")
    ax.set_ylabel("y [mm] (away from user)")
    ax.set_title("workspace, seen from above")
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
