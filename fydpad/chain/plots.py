"""Plots of the chain: the identified TF set (magnitude, phase, coherence) and the
compensation check (target, uncompensated, compensated spectra: Felicetti 2022 Fig. 8b)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fydpad.chain.check import CheckResult
from fydpad.chain.tf_file import TfSet
from fydpad.plots import clip_log_axis, label, legend_outside


def plot_tf_set(path: str | Path, tfs: TfSet) -> Path:
    """|TF| (dB), phase (deg) and coherence per stiffness over the excitation band."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True, constrained_layout=True)
    lo, hi = tfs.band_hz
    for e in tfs.entries:
        est = e.estimate
        sel = (est.freqs_hz >= lo) & (est.freqs_hz <= hi)
        f = est.freqs_hz[sel]
        axes[0].plot(f, 20 * np.log10(np.abs(est.tf[sel])),
                     label=f"k = {e.stiffness_n_per_mm:g} N/mm")
        axes[1].plot(f, np.degrees(np.unwrap(np.angle(est.tf[sel]))))
        axes[2].plot(f, est.coherence[sel])
    axes[0].set_ylabel(label("|TF|", f"dB re 1 {tfs.output_unit}/{tfs.input_unit}"))
    axes[1].set_ylabel(label("phase", "deg"))
    axes[2].set_ylabel("coherence")
    axes[2].axhline(0.9, color="k", lw=0.8, ls="--")
    axes[2].set_ylim(0, 1.02)
    axes[2].set_xlabel(label("frequency", "Hz"))
    legend_outside(axes[0])
    axes[0].set_title(f"chain TF, channel '{tfs.channel}' at {tfs.rate_hz:g} Hz "
                      "(CPSD_yx / PSD_x, Welch)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_check(path: str | Path, res: CheckResult, title: str = "") -> Path:
    """PSD of the target and of the reproduced signals; the compared bins shaded."""
    fig, ax = plt.subplots(figsize=(9, 5), constrained_layout=True)
    f = res.freqs_hz
    ax.semilogy(f, res.target_psd, "k", lw=2, label="target")
    ax.semilogy(f, res.uncompensated_psd, label="uncompensated (gain only)")
    ax.semilogy(f, res.compensated_psd, label="compensated (live min-phase FIR)")
    if res.offline_psd is not None:
        ax.semilogy(f, res.offline_psd, ls=":", label="compensated offline (FFT, eqs. 2-4)")
    if res.compared.any():
        ax.axvspan(f[res.compared].min(), f[res.compared].max(), color="0.9", zorder=0,
                   label="compared band")
    ax.axvline(res.resonance_hz, color="r", lw=0.8, ls="--", label="resonance")
    fig_ = res.figures
    ax.set_title(title or (f"k = {fig_['stiffness_n_per_mm']:g} N/mm: compensated within "
                           f"{fig_['compensated_max_error_db']:.1f} dB, uncompensated "
                           f"{fig_['uncompensated_error_at_resonance_db']:+.1f} dB at "
                           "resonance"))
    ax.set_xlabel(label("frequency", "Hz"))
    ax.set_ylabel(label("PSD", "(m/s^2)^2/Hz"))
    ax.grid(True, which="both", alpha=0.3)
    # The band that matters: the compared bins' levels, a decade of room below; outside
    # it the target falls by many decades and would squeeze the comparison.
    band = res.compared if res.compared.any() else np.ones_like(f, bool)
    clip_log_axis(ax, res.target_psd[band], res.uncompensated_psd[band],
                  res.compensated_psd[band])
    legend_outside(ax)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
