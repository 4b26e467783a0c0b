"""Tracking figures of docs/recording_format.md: MAE (paper eq. 6), lag, latency; Fig. 11 plot.

Pure functions over arrays in one clock (the master's).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

AXES = ("x", "y", "z")


def scored_rows(t_s: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Mask of the samples from the first contact on (docs/recording_format.md)."""
    idx = np.flatnonzero(contact)
    mask = np.zeros(t_s.size, bool)
    if idx.size:
        mask[idx[0]:] = True
    return mask


def interp_log(t_query: np.ndarray, t_log: np.ndarray, p_log: np.ndarray) -> np.ndarray:
    """Slave log (N, 3) interpolated at ``t_query``; NaN outside the log's time span."""
    out = np.full((t_query.size, 3), np.nan)
    if t_log.size < 2:
        return out
    inside = (t_query >= t_log[0]) & (t_query <= t_log[-1])
    for j in range(3):
        out[inside, j] = np.interp(t_query[inside], t_log, p_log[:, j])
    return out


def mae_per_axis(t_s: np.ndarray, master_mm: np.ndarray, contact: np.ndarray,
                 t_log_s: np.ndarray, slave_mm: np.ndarray, shift_s: float = 0.0) -> np.ndarray:
    """Eq. (6) per axis: |master(t_i) - slave(t_i + shift)| averaged over the scored samples.

    Samples where the master has no value on an axis (x, y without contact) are skipped.
    """
    mask = scored_rows(t_s, contact)
    s = interp_log(t_s[mask] + shift_s, t_log_s, slave_mm)
    err = np.abs(master_mm[mask] - s)
    with np.errstate(invalid="ignore"):
        return np.array([np.nanmean(err[:, j]) if np.any(np.isfinite(err[:, j])) else np.nan
                         for j in range(3)])


def best_lag_s(t_s: np.ndarray, master_mm: np.ndarray, contact: np.ndarray,
               t_log_s: np.ndarray, slave_mm: np.ndarray,
               search_s: tuple[float, float] = (-0.1, 0.3), step_s: float = 0.001) -> float:
    """The shift of the slave log that minimises the mean MAE over the axes."""
    shifts = np.arange(search_s[0], search_s[1] + step_s / 2, step_s)
    costs = [np.nanmean(mae_per_axis(t_s, master_mm, contact, t_log_s, slave_mm, s))
             for s in shifts]
    return float(shifts[int(np.nanargmin(costs))])


def axes_dict(v: np.ndarray, ndigits: int = 3) -> dict[str, float | None]:
    return {a: (None if not np.isfinite(x) else round(float(x), ndigits))
            for a, x in zip(AXES, v, strict=True)}


def latency_ms(latency_s: np.ndarray) -> dict[str, float | None]:
    if latency_s.size == 0:
        return {"p50": None, "p99": None}
    return {"p50": round(float(np.percentile(latency_s, 50)) * 1e3, 3),
            "p99": round(float(np.percentile(latency_s, 99)) * 1e3, 3)}


def plot_tracking(path: str | Path, t_s: np.ndarray, master_mm: np.ndarray,
                  t_log_s: np.ndarray, slave_mm: np.ndarray,
                  baseline: tuple[np.ndarray, np.ndarray] | None = None,
                  title: str = "") -> Path:
    """Master and slave per axis over time, like the paper's Fig. 11; writes a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    labels = ("x (mm)", "y (mm)", "z indentation (mm)")
    for j, ax in enumerate(axs):
        ax.plot(t_s, master_mm[:, j], ".", ms=3, label="master (finger)")
        ax.plot(t_log_s, slave_mm[:, j], "-", lw=1, label="slave (robot, predicted)")
        if baseline is not None:
            ax.plot(baseline[0], baseline[1][:, j], "-", lw=1, alpha=0.6,
                    label="slave, paper condition (10 Hz, hold)")
        ax.set_ylabel(labels[j])
        ax.grid(alpha=0.3)
    axs[0].legend(loc="upper right", fontsize=8)
    axs[-1].set_xlabel("time (s)")
    if title:
        axs[0].set_title(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
