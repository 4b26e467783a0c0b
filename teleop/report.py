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


def truth_breakdown(t_s: np.ndarray, master_mm: np.ndarray, contact: np.ndarray,
                    t_log_s: np.ndarray, slave_mm: np.ndarray, t_truth_s: np.ndarray,
                    truth_mm: np.ndarray, truth_contact: np.ndarray) -> dict:
    """Where the error against the true finger comes from, eq. (6) per axis, each part
    over the truth's scored samples (from the first true contact on):

    - ``master_vs_truth``: the master stream against the truth: x and y are the tracked
      contact centroid's error, z the indentation's against the true depth;
    - ``slave_vs_master``: the slave against the master stream (the link and the robot);
    - ``slave_vs_truth``: the slave against the truth (end to end, ``truth_mae_mm``).

    ``t_truth_s`` on the master's clock; ``truth_mm`` rows x, y, depth."""
    mask = scored_rows(t_truth_s, truth_contact)
    tq = t_truth_s[mask]
    master_at = np.full((tq.size, 3), np.nan)
    for j in range(3):
        ok = np.isfinite(master_mm[:, j])
        if np.count_nonzero(ok) >= 2:
            inside = (tq >= t_s[ok][0]) & (tq <= t_s[ok][-1])
            master_at[inside, j] = np.interp(tq[inside], t_s[ok], master_mm[ok, j])
    # The master has no x, y without contact: compare x, y where both touch.
    both = np.asarray(truth_contact, bool)[mask]
    near = _nearest_contact(tq, t_s, contact)
    master_at[~(both & near), :2] = np.nan
    err = np.abs(master_at - truth_mm[mask])
    with np.errstate(invalid="ignore"):
        sensing = np.array([np.nanmean(err[:, j]) if np.any(np.isfinite(err[:, j])) else np.nan
                            for j in range(3)])
    return {
        "master_vs_truth": axes_dict(sensing),
        "slave_vs_master": axes_dict(mae_per_axis(t_s, master_mm, contact, t_log_s, slave_mm)),
        "slave_vs_truth": axes_dict(mae_per_axis(t_truth_s, truth_mm, truth_contact,
                                                 t_log_s, slave_mm)),
    }


def _nearest_contact(tq: np.ndarray, t_s: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """The master's contact flag at its sample nearest each query time."""
    if t_s.size == 0:
        return np.zeros(tq.size, bool)
    i = np.clip(np.searchsorted(t_s, tq), 1, max(t_s.size - 1, 1))
    i = np.where(np.abs(t_s[i - 1] - tq) <= np.abs(t_s[np.minimum(i, t_s.size - 1)] - tq),
                 i - 1, np.minimum(i, t_s.size - 1))
    return np.asarray(contact, bool)[i]


_BREAKDOWN_LABELS = (
    ("master_vs_truth", "tracking (x, y) and indentation (z) vs truth"),
    ("slave_vs_master", "slave vs master stream (link, robot)"),
    ("slave_vs_truth", "slave vs truth (end to end)"),
)


def breakdown_lines(report: dict) -> list[str]:
    """``truth_breakdown_mm`` of a report as lines to print first, the largest part
    named; no lines when the report has none (a recording without truth)."""
    parts = report.get("truth_breakdown_mm")
    if not parts:
        return []

    def fmt(v: float | None) -> str:
        return "  -  " if v is None else f"{v:5.2f}"

    width = max(len(label) for _, label in _BREAKDOWN_LABELS)
    head = "error against the true finger, MAE mm"
    lines = [f"{head:<{width + 2}}  " + "  ".join(f"{a:>5}" for a in AXES)]
    for key, label in _BREAKDOWN_LABELS:
        d = parts.get(key)
        if d is None:
            continue
        lines.append(f"  {label:<{width}}  " + "  ".join(fmt(d.get(a)) for a in AXES))
    # The dominant part: the largest of the sensing's and the link's axes.
    cands = [(v, key, a) for key in ("master_vs_truth", "slave_vs_master")
             for a, v in parts.get(key, {}).items() if v is not None]
    if cands:
        v, key, a = max(cands)
        what = {"x": "tracking x", "y": "tracking y", "z": "indentation"}[a] \
            if key == "master_vs_truth" else f"link {a}"
        lines.append(f"  largest part: {what}, {v:.2f} mm")
    return lines


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
    # lazy: matplotlib loads only when a plot is asked for; Agg before pyplot (no display)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after use("Agg")

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
