"""Synthesized against recorded texture signals (Bianchi 2015 IV-A), on the DFT321 signal
high-passed as the fit, before any drive filter: Welch spectra in 4 Hz bins over 20-500 Hz,
their Pearson correlation (the paper's "correlation in frequency", 0.681; also on dB
spectra) and log-spectral distance, band energies, and the time correlation (the paper's
0.263; near 0 for independent realisations of any correct model, reported for comparison).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal as ss
from numpy.typing import ArrayLike, NDArray

from fydpad.errors import UserError
from fydpad.texture.family import RateMismatch, TextureFamily, finger_from_scan, runs
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]
BAND_HZ = (20.0, 500.0)
BIN_HZ = 4.0
ENERGY_BANDS_HZ = ((20, 50), (50, 100), (100, 200), (200, 500), (165, 220))
#: The targets: the power-spectrum correlation at least this, and the log-spectral
#: distance within this of what a second recording of the surface scores (the ceiling).
TARGET_PSD_CORRELATION = 0.95
TARGET_LSD_OVER_CEILING_DB = 0.25


def welch_psd(x: ArrayLike, fs: float, mask: ArrayLike | None = None) -> tuple[Array, Array]:
    """Welch PSD in ``BIN_HZ`` bins (Hann, 50 %), averaged over the True runs of mask."""
    x = np.asarray(x, float)
    nper = round(fs / BIN_HZ)
    pieces = [(0, x.size)] if mask is None else runs(mask, nper)
    acc, weight, f = None, 0, None
    for a, b in pieces:
        if b - a < nper:
            continue
        f, p = ss.welch(x[a:b], fs, nperseg=nper, noverlap=nper // 2, window="hann")
        acc = p * (b - a) if acc is None else acc + p * (b - a)
        weight += b - a
    if acc is None:
        raise ValueError(f"fewer than {nper} samples to estimate a {BIN_HZ:g} Hz-bin spectrum")
    return f, acc / weight


def _band(f: Array, band: tuple[float, float]) -> NDArray[np.bool_]:
    return (f >= band[0]) & (f <= band[1])


def psd_correlation(p1: Array, p2: Array) -> float:
    return float(np.corrcoef(p1, p2)[0, 1])


def lsd_db(p1: Array, p2: Array) -> float:
    d = 10 * np.log10(p1 / p2)
    return float(np.sqrt(np.mean(d * d)))


@dataclass
class Comparison:
    psd_correlation: float
    psd_correlation_db: float
    lsd_db: float
    time_correlation: float
    band_energy_recorded: dict[str, float]
    band_energy_synthesized: dict[str, float]


def compare(recorded: Array, synthesized: Array, fs: float, mask: ArrayLike | None = None
            ) -> tuple[Comparison, Array, Array, Array]:
    """Metrics of two equally long signals over the mask; also (f, P_rec, P_syn)."""
    f, pr = welch_psd(recorded, fs, mask)
    _, ps = welch_psd(synthesized, fs, mask)
    sel = _band(f, BAND_HZ)
    m = np.ones(recorded.size, bool) if mask is None else np.asarray(mask, bool)
    r, s = recorded[m], synthesized[m]
    tc = float(np.corrcoef(r, s)[0, 1]) if r.size > 2 else float("nan")
    df = f[1] - f[0]
    energy = {
        lab: {f"{lo}-{hi}_hz": float(np.sum(p[_band(f, (lo, hi))]) * df)
              for lo, hi in ENERGY_BANDS_HZ}
        for lab, p in (("r", pr), ("s", ps))
    }
    c = Comparison(psd_correlation(pr[sel], ps[sel]),
                   psd_correlation(10 * np.log10(pr[sel]), 10 * np.log10(ps[sel])),
                   lsd_db(pr[sel], ps[sel]), tc, energy["r"], energy["s"])
    return c, f, pr, ps


def render_stroke(family: TextureFamily, scan: Scan, channel: str = "vibration",
                  seed: int = 0, name: str = "") -> Array:
    """A new stroke of ``family`` along the scan's finger stream, its noise (if any) drawn
    from ``seed``; a model that cannot render it is a UserError naming the scan and
    ``name`` (the model)."""
    if "seed" in family.parameters:
        family.set_parameter("seed", seed)
    family.reset()
    where = f"{name}: " if name else ""
    try:
        return family.render(finger_from_scan(scan), channel)
    except RateMismatch as exc:
        raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz, "
                        f"{where}{exc}") from None
    except ValueError as exc:
        raise UserError(f"{scan.path}: {where}{exc}") from None


def evaluate_family(family: TextureFamily, scan: Scan, *, seed: int = 0,
                    mask: ArrayLike | None = None, name: str = ""
                    ) -> tuple[Comparison, Array, Array, Array]:
    """The family's vibration along the scan's stroke (:func:`render_stroke`) against the
    scan, over ``mask`` (default: the samples the family covers); also (f, P_rec, P_syn)."""
    syn = render_stroke(family, scan, seed=seed, name=name)
    rec = preprocess(scan.acc, scan.fs_hz, family.highpass_hz)
    return compare(rec, syn, scan.fs_hz,
                   family.covers(scan.speed_mm_s) if mask is None else mask)


def evaluate_second(family: TextureFamily, scan: Scan, second: Scan,
                    mask: ArrayLike | None = None) -> Comparison:
    """A second recording scored against the scan as :func:`evaluate_family` scores the
    family (the ceiling), over ``mask`` and the second's samples the family covers."""
    hp = family.highpass_hz
    mask = family.covers(scan.speed_mm_s) if mask is None else np.asarray(mask, bool)
    c, *_ = compare(preprocess(scan.acc, scan.fs_hz, hp),
                    preprocess(second.acc, second.fs_hz, hp), scan.fs_hz,
                    mask & family.covers(second.speed_mm_s))
    return c


@dataclass
class Ceiling:
    """A second recording scored against the scan as a model is: what two realisations
    of the texture score against each other."""

    psd_correlation: float
    lsd_db: float


def ceiling(recorded_psd: Array, second_psd: Array, f_hz: Array) -> Ceiling:
    """The ceiling from the two recordings' Welch spectra."""
    sel = _band(f_hz, BAND_HZ)
    return Ceiling(psd_correlation(recorded_psd[sel], second_psd[sel]),
                   lsd_db(recorded_psd[sel], second_psd[sel]))


def unfair_ceiling(scan_speeds_mm_s: Array, second_speeds_mm_s: Array, fs_hz: float,
                   tolerance_mm_s: float, scan_surface: str | None = None,
                   second_surface: str | None = None) -> str | None:
    """Why a second recording sets no fair ceiling for the scan, or None: another
    surface, a median speed beyond the tolerance from the scan's, or less than half the
    scan's duration (its spectrum scatters more, raising the ceiling)."""
    if scan_surface and second_surface and scan_surface != second_surface:
        return f"it is of {second_surface!r}, the scan of {scan_surface!r}"
    v1, v2 = float(np.median(scan_speeds_mm_s)), float(np.median(second_speeds_mm_s))
    if abs(v2 - v1) > tolerance_mm_s:
        return (f"its median speed {v2:.1f} mm/s is more than {tolerance_mm_s:g} mm/s from "
                f"the scan's {v1:.1f}")
    if second_speeds_mm_s.size < 0.5 * scan_speeds_mm_s.size:
        return (f"it holds {second_speeds_mm_s.size / fs_hz:.1f} s within the model's "
                f"speeds, less than half the scan's {scan_speeds_mm_s.size / fs_hz:.1f} s")
    return None


def meets_targets(c: Comparison, ceil: Ceiling) -> bool:
    """The targets: correlation >= 0.95 and LSD <= the ceiling's + 0.25 dB."""
    return (c.psd_correlation >= TARGET_PSD_CORRELATION
            and c.lsd_db <= ceil.lsd_db + TARGET_LSD_OVER_CEILING_DB)


@dataclass(frozen=True)
class MeansVerdict:
    """The targets judged on the means of several strokes (:func:`verdict_on_means`)."""

    psd_correlation: float
    lsd_over_ceiling_db: float
    psd_correlation_se: float | None  # None with one stroke
    lsd_over_ceiling_se_db: float | None
    met: bool
    decided: bool  # the verdict stands with both means moved two standard errors


def verdict_on_means(corr: ArrayLike, lsd_over_ceiling_db: ArrayLike) -> MeansVerdict:
    """The targets on the means over the strokes (each against its own second recording:
    one pair is two random draws). Decided: both means clear their limits by two standard
    errors (met), or one misses by two."""
    c = np.asarray(corr, float)
    d = np.asarray(lsd_over_ceiling_db, float)
    corr_mean, gap = float(np.mean(c)), float(np.mean(d))
    met = corr_mean >= TARGET_PSD_CORRELATION and gap <= TARGET_LSD_OVER_CEILING_DB
    if d.size < 2:
        return MeansVerdict(corr_mean, gap, None, None, met, False)
    c_se = float(np.std(c, ddof=1) / np.sqrt(c.size))
    g_se = float(np.std(d, ddof=1) / np.sqrt(d.size))
    if met:
        decided = (gap + 2 * g_se <= TARGET_LSD_OVER_CEILING_DB
                   and corr_mean - 2 * c_se >= TARGET_PSD_CORRELATION)
    else:
        decided = (gap - 2 * g_se > TARGET_LSD_OVER_CEILING_DB
                   or corr_mean + 2 * c_se < TARGET_PSD_CORRELATION)
    return MeansVerdict(corr_mean, gap, c_se, g_se, met, decided)
