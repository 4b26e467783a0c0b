"""Plots a person would rather look at than read (matplotlib, no display needed).

The project's one plot style: axis titles "quantity (unit)", legends outside the data,
a log axis clipped to the band that matters (the values inside it, not a target that
falls by decades outside it)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike


def label(quantity: str, unit: str = "") -> str:
    """An axis title: ``quantity (unit)``."""
    return f"{quantity} ({unit})" if unit else quantity


def legend_outside(ax, **kwargs) -> None:
    """The legend to the right of the axes, never over the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8,
              **kwargs)


def clip_log_axis(ax, *series: ArrayLike, decades_below: float = 1.0,
                  axis: str = "y") -> None:
    """Limit a log axis to the positive values of ``series`` (the band that matters),
    with ``decades_below`` decades of room under the smallest and a little above."""
    values = np.concatenate([np.ravel(np.asarray(v, float)) for v in series]) if series \
        else np.empty(0)
    values = values[np.isfinite(values) & (values > 0)]
    if values.size == 0:
        return
    low, high = values.min() / 10.0 ** decades_below, values.max() * 2.0
    (ax.set_ylim if axis == "y" else ax.set_xlim)(low, high)


def plot_teleop(path: str | Path, t_s: ArrayLike, master_mm: ArrayLike, t_slave_s: ArrayLike,
                slave_mm: ArrayLike, baseline: tuple[ArrayLike, ArrayLike] | None = None,
                title: str = "") -> Path:
    """Master (the finger) and slave (the robot) per axis over time, like the paper's
    Fig. 11, with the slave under the paper's condition when it was run."""
    master = np.asarray(master_mm, float)
    slave = np.asarray(slave_mm, float)
    fig, axs = plt.subplots(3, 1, figsize=(10, 7), sharex=True, constrained_layout=True)
    names = (label("x", "mm"), label("y", "mm"), label("z, indentation", "mm"))
    for j, ax in enumerate(axs):
        ax.plot(t_s, master[:, j], ".", ms=3, color="0.45", label="master (finger, tracked)")
        ax.plot(t_slave_s, slave[:, j], "-", lw=1.2, color="C0", label="slave (robot)")
        if baseline is not None:
            ax.plot(baseline[0], np.asarray(baseline[1], float)[:, j], "-", lw=1, alpha=0.7,
                    color="C3", label="slave, paper's condition (10 Hz, hold)")
        ax.set_ylabel(names[j])
        ax.grid(alpha=0.3)
    legend_outside(axs[0])
    axs[-1].set_xlabel(label("time", "s"))
    return save_figure(fig, path, title)


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
    series = [("x_mm", x, label("x", "mm")), ("y_mm", y, label("y", "mm"))]
    if has_ind:
        series.append(("indentation_mm", ind, label("indentation", "mm")))
    axes = []
    for i, (key, values, ylabel) in enumerate(series):
        ax = fig.add_subplot(grid[i, 0], sharex=axes[0] if axes else None)
        if truth is not None and key in truth:
            ax.plot(truth["t_s"], truth[key], color="0.6", lw=2.5, label="truth")
        ax.plot(t, values, color="C0", lw=1.0, label="tracked")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        axes.append(ax)
    axes[-1].set_xlabel(label("time", "s"))
    legend_outside(axes[0])
    ax = fig.add_subplot(grid[:, 1])
    w, h = workspace_mm
    ax.add_patch(plt.Rectangle((-w / 2, -h / 2), w, h, fill=False, color="0.3"))
    if truth is not None:
        ax.plot(truth["x_mm"], truth["y_mm"], color="0.6", lw=2.5, label="truth")
    sc = ax.scatter(x, y, c=t, s=6, cmap="viridis", label="tracked")
    fig.colorbar(sc, ax=ax, label=label("time", "s"), shrink=0.7)
    ax.set_xlim(-w / 2 - 5, w / 2 + 5)
    ax.set_ylim(-h / 2 - 5, h / 2 + 5)
    ax.set_aspect("equal")
    ax.set_xlabel(label("x, to the user's right", "mm"))
    ax.set_ylabel(label("y, away from the user", "mm"))
    ax.set_title("workspace, seen from above")
    return save_figure(fig, path, title)


def save_figure(fig, path: str | Path, title: str = "") -> Path:
    """Title the figure, write it to ``path`` and free it."""
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
