"""Periodic surfaces: the harmonics of a spatial period, following the finger.

A grating, a mesh, a weave or a knurl is periodic along the stroke, so part of its
vibration is a set of lines at n v / lambda that move with the finger's speed v. An
all-pole model fitted per speed pools the hand's +-5 mm/s of wander and smears those
lines into bands (docs/texture.md, "The combs"); here they are modelled as what they
are, deterministic in the position along the stroke:

    a_lines(t) = sum_n A_n(v(t)) cos(2 pi n s(t) / lambda + psi_n),   s(t) = int v dt

beside the paper's eq. 5 process, which is fitted on what the lines leave (the
residual). The synthesis integrates the same speed it is given, so a held-out stroke's
lines spread exactly as its hand's speed spread them.

Fit (:func:`fit_lines`), on the preprocessed (high-passed, DFT321) signal of each stroke:

1. The period (:func:`estimate_period`): each stroke resampled on its arc length s,
   where the lines are at fixed spatial frequencies n / lambda whatever the speed; the
   candidate that puts significant peaks on the most harmonics wins, then lambda is
   refined on the coherent power of its strongest harmonics (the high harmonics need it
   to 1e-5: their phase over a 100 mm stroke). Without a comb, a rib: one line that is
   the strongest peak of every stroke able to see it, with the harmonics that stand as
   peaks (corduroy's wale, searched from 10 Hz, :func:`_rib`).
2. Per stroke and harmonic, the complex amplitude as (v / med)^2 times a piecewise
   linear function of speed, by least squares on the signal demodulated at the
   harmonic's phase 2 pi n s / lambda (the harmonics are orthogonal over a stroke of many
   periods); what noise alone gives such a fit follows from the spectrum of what every
   harmonic's fit leaves (:func:`_noise_of_fit`).
3. Per 0.5 mm/s speed bin, pooled over strokes: the amplitude^2 less the noise's; a
   harmonic is kept at a speed where it stands ``snr`` times above that noise (or one
   stroke's own fit stands far above it). Where no stroke's speeds reach, a factor model
   log P_n(v) = u_n + t(n v / lambda) + g(v) (a surface's harmonic levels through a
   tool's response, scaled by the drive), corrected by its error at the nearest bins with
   the line.
4. The residual: each stroke less its kept harmonics, up to where the table's taper
   starts (96 % of Nyquist; the all-pole part carries what lies above). Only the samples
   within a stroke's fitted speed range (+-45 % of its median) have their lines removed,
   so only they go to the stochastic fit (a ramp at the ends of a stroke does not).

The phases psi_n are those of the slowest stroke (where every harmonic is in band):
they give the waveform its shape (a rectangular grating's edges), not its spectrum.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.ndimage as ndi
import scipy.signal as ss
import scipy.sparse as sparse
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.lpc.analysis import runs

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: A stroke's samples within this fraction of its median speed carry its line fit.
SPEED_SPAN = 0.45
#: Samples where the speed changes faster than this (per second, relative) carry no fit,
#: nor those within EDGE_S of them or of a stroke's ends (a hand's sway: 0.5 /s at most;
#: a stroke's start: 3 /s and more).
MAX_SPEED_RATE = 1.5
EDGE_S = 0.25
#: Speed grid of the amplitude table (mm/s).
GRID_STEP_MM_S = 0.5
#: A rib without a comb (:func:`_rib`) is searched from here, a little under the 10 Hz
#: high-pass's corner (a 2.5 mm rib sits at 4-16 Hz at 10-40 mm/s, below the comb
#: search's 15 Hz but for the fastest strokes; a hand asked for 30 mm/s wanders down to
#: 25 in a stroke, where the rib is at 10 Hz: searched from the corner, only the 40 mm/s
#: strokes saw it, and corduroy got no lines); its line must be the strongest peak of
#: every stroke that can see it, in at least RIB_MIN_STROKES strokes whose median speeds span
#: RIB_MIN_SPEED_RATIO (a hum on a constant-speed rig stands at one k in every stroke).
RIB_F_LO = 8.0
RIB_MIN_STROKES = 2
RIB_MIN_SPEED_RATIO = 1.2
#: ... among the RIB_TOP_PEAKS strongest peaks of each of them (and the strongest in at
#: least half: a rounded rib's 2nd harmonic may outdo its line in one stroke), holding
#: RIB_MIN_SCORE of their spatial power (_comb_score; a comb needs MIN_COMB_SCORE, but a
#: rib on a rough surface, 0.003 mm RMS, scored 0.10; fit_lines' MIN_SHARE follows).
RIB_TOP_PEAKS = 3
RIB_MIN_SCORE = 0.1
#: Harmonics up to this fraction of Nyquist (the scans' anti-alias filter ends there);
#: the renderer tapers them from TAPER_START of Nyquist so none drops out with a click.
BAND_TOP = 0.99
TAPER_START = 0.96
#: A kept harmonic's pooled power over what noise alone gives its fit.
DEFAULT_SNR = 3.0
#: A stroke's own fit this many times over ``snr`` makes its line present at that row.
OWN_SNR_FACTOR = 4.0
#: Less of the in-band power than this in the lines: no line model (the all-pole
#: model holds such weak lines as well).
MIN_SHARE = 0.05
#: A bin needs this much data (seconds, pooled) to say something about a harmonic.
MIN_BIN_S = 0.25
#: The comb's teeth must hold this much more of the spatial power than their share of
#: the band (a smooth spectrum: 0).
MIN_COMB_SCORE = 0.2
#: Harmonics modelled at most (a long period at a slow speed has thousands in band); the
#: wavetable then has 32 points per cycle of the highest in 16384.
MAX_HARMONICS = 512
#: Knot spacing of a harmonic's amplitude along speed, in Hz of the harmonic's frequency:
#: the scale on which a tool resonance changes it (a mode of Q 10 at 300 Hz is 30 Hz wide).
KNOT_HZ = 20.0
#: Speed bins of the per-harmonic fits (mm/s): the amplitudes change over 1 mm/s or more.
FINE_MM_S = 0.01
_CHUNK = 64  # harmonics per matrix product (memory: samples x chunk complex)


@dataclass
class LineSpectrum:
    """Harmonic amplitudes of a period over a speed grid (the model file's ``lines``)."""

    period_mm: float
    v_mm_s: Array  # (m,) ascending, GRID_STEP_MM_S apart
    amplitude: Array  # (m, N) peak amplitude of harmonic n = 1..N, m/s^2
    phase_rad: Array  # (N,)

    @property
    def harmonics(self) -> int:
        return int(self.amplitude.shape[1])

    def amplitudes_at(self, speed_mm_s: float) -> Array:
        """A_n at a speed: linear between grid rows, the edge rows beyond."""
        v = self.v_mm_s
        x = float(np.clip((speed_mm_s - v[0]) / (v[1] - v[0]) if v.size > 1 else 0.0,
                          0.0, v.size - 1))
        k = min(int(x), v.size - 2) if v.size > 1 else 0
        w = x - k
        if v.size == 1:
            return self.amplitude[0].copy()
        return (1 - w) * self.amplitude[k] + w * self.amplitude[k + 1]

    def wavetable(self, points: int | None = None) -> Array:
        """One period of the waveform at every grid speed: (m, points + 1), the last
        column repeating the first (so a linear interpolation needs no wrap)."""
        n = self.harmonics
        top = int(np.max(np.nonzero(self.amplitude.any(axis=0))[0], initial=-1)) + 1
        if points is None:  # 32 points per cycle of the highest harmonic: images < -30 dB
            points = int(min(max(256, 2 ** math.ceil(math.log2(max(32 * top, 1)))), 16384))
        spec = np.zeros((self.v_mm_s.size, points // 2 + 1), complex)
        m = min(n, points // 2 - 1)
        spec[:, 1:m + 1] = self.amplitude[:, :m] * np.exp(1j * self.phase_rad[:m])
        table = np.fft.irfft(spec, points, axis=1) * (points / 2)
        return np.concatenate([table, table[:, :1]], axis=1)

    def to_json(self) -> dict:
        return {
            "period_mm": float(self.period_mm),
            "v_mm_s": [round(float(v), 6) for v in self.v_mm_s],
            "phase_rad": [round(float(p), 6) for p in self.phase_rad],
            "amplitude": [[float(f"{a:.6g}") for a in row] for row in self.amplitude],
            "units": {"amplitude": "m/s^2 (peak)", "v_mm_s": "mm/s", "period_mm": "mm"},
        }

    @classmethod
    def from_json(cls, d: object, where: str) -> LineSpectrum:
        """Checked: each error names ``lines.<key>`` in ``where`` (the file)."""
        if not isinstance(d, dict):
            raise UserError(f"{where}: key 'lines' must be an object")

        def arr(key: str, ndim: int) -> Array:
            if key not in d:
                raise UserError(f"{where}: missing key 'lines.{key}'")
            try:
                a = np.asarray(d[key], float)
            except (TypeError, ValueError):
                raise UserError(f"{where}: key 'lines.{key}' must be numbers") from None
            if a.ndim != ndim or a.size == 0 or not np.all(np.isfinite(a)):
                raise UserError(f"{where}: key 'lines.{key}' must be a non-empty "
                                f"{'list' if ndim == 1 else 'table'} of finite numbers")
            return a

        period = d.get("period_mm")
        if isinstance(period, bool) or not isinstance(period, int | float) or not (
                math.isfinite(period) and period > 0):
            raise UserError(f"{where}: key 'lines.period_mm' must be a number > 0, "
                            f"not {period!r}")
        if period < 1e-3 or period > 1e3:
            raise UserError(f"{where}: key 'lines.period_mm' must be within 0.001-1000 mm, "
                            f"not {period!r}")
        v, phase, amp = arr("v_mm_s", 1), arr("phase_rad", 1), arr("amplitude", 2)
        step = np.diff(v)
        if (v[0] < 0 or v[-1] > 1e4 or np.any(step < 0.01)
                or (step.size and np.any(np.abs(step - step[0]) > 1e-6 * step[0]))):
            raise UserError(f"{where}: key 'lines.v_mm_s' must be speeds 0-10000 mm/s, "
                            "ascending in equal steps of at least 0.01 mm/s")
        if amp.shape != (v.size, phase.size):
            raise UserError(f"{where}: key 'lines.amplitude' must have one row per "
                            f"'lines.v_mm_s' ({v.size}) and one column per 'lines.phase_rad' "
                            f"({phase.size}), not {amp.shape[0]} x {amp.shape[1]}")
        if np.any(amp < 0):
            raise UserError(f"{where}: key 'lines.amplitude' must be >= 0")
        return cls(float(period), v, amp, phase)


@dataclass
class LineFit:
    """What :func:`fit_lines` found: the spectrum (None: no periodic part worth it),
    each stroke's residual, and the samples the stochastic fit may use."""

    spectrum: LineSpectrum | None
    residuals: list[Array]
    keep: list[Mask]
    period_mm: float | None
    share: float  # of the kept samples' power, in the lines
    note: str

    @classmethod
    def none(cls, signals: Sequence[Array], note: str, period_mm: float | None = None,
             share: float = 0.0) -> LineFit:
        """No line model: the residuals are the signals, every sample may be used."""
        return cls(None, list(signals), [np.ones(y.size, bool) for y in signals], period_mm,
                   share, note)


def arc_length_mm(speed_mm_s: Array, fs_hz: float) -> Array:
    """s(t) = int v dt as the renderer integrates it (one step of v / fs per sample)."""
    return np.cumsum(np.asarray(speed_mm_s, float)) / fs_hz


def _stroke_span(v: Array, speed_range: tuple[float, float], fs_hz: float
                 ) -> tuple[float, Mask] | None:
    """(median speed, the samples that carry the stroke's line fit), or None: within
    SPEED_SPAN of the median and within the range, and not where the speed changes faster
    than MAX_SPEED_RATE of itself per second (a stroke's start and end: the tool's
    resonance does not follow lines that sweep that fast, and the DFT321 window smears
    them), nor within a window of that or of the stroke's ends."""
    lo, hi = speed_range
    inr = (v >= lo) & (v <= hi) & (v > 0)
    if inr.sum() < 16:
        return None
    med = float(np.median(v[inr]))
    fast = np.abs(np.gradient(v) * fs_hz) > MAX_SPEED_RATE * np.maximum(v, 1.0)
    guard = max(1, round(EDGE_S * fs_hz))
    fast = ndi.binary_dilation(fast, np.ones(2 * guard + 1, bool))
    fast[:guard] = fast[-guard:] = True
    return med, inr & ~fast & (np.abs(v - med) < SPEED_SPAN * med)


def _longest_run(mask: Mask) -> tuple[int, int]:
    return max(runs(mask), key=lambda r: r[1] - r[0], default=(0, 0))


@dataclass
class _Stroke:
    index: int  # of the signal it comes from
    y: Array
    v: Array
    s: Array  # arc length, mm
    med: float
    valid: Mask


@dataclass
class _Spectrum:
    """A stroke's spatial periodogram and its peaks (sub-bin interpolated)."""

    k: Array  # cycles/mm
    k_lo: float  # the harmonics' band for every sample of the run
    k_hi: float
    power: Array
    peaks_k: Array  # strongest first


_PAD = 2  # zero padding of the spatial periodogram
_TOL_BINS = 1.5 * _PAD  # a peak matches a harmonic within this many padded bins


def _spatial_spectrum(st: _Stroke, f_lo: float, f_hi: float) -> _Spectrum | None:
    """Hann periodogram of the stroke's longest valid run on a uniform arc-length grid,
    where the harmonics stand at n / lambda whatever the speed."""
    a, b = _longest_run(st.valid)
    if b - a < 256:
        return None
    s, y, v = st.s[a:b], st.y[a:b], st.v[a:b]
    ds = 0.5 * float(np.median(np.diff(s)))  # twice the samples: no harmonic folds
    if not ds > 0:
        return None
    su = np.arange(s[0], s[-1], ds)
    yu = np.interp(su, s, y) * np.hanning(su.size)
    n = su.size * _PAD
    k = np.fft.rfftfreq(n, ds)
    p = np.abs(np.fft.rfft(yu, n)) ** 2 + 1e-300
    ratio = p / (ndi.median_filter(p, size=20 * _PAD + 1, mode="nearest") + 1e-300)
    k_lo, k_hi = f_lo / float(v.min()), f_hi / float(v.max())
    sel = np.zeros(k.size, bool)
    sel[1:-1] = (p[1:-1] >= p[:-2]) & (p[1:-1] >= p[2:])
    sel &= (ratio > 30.0) & (k >= k_lo) & (k <= k_hi)
    j = np.flatnonzero(sel)
    j = j[np.argsort(p[j])[::-1][:40]]
    # Parabola through the log power of the peak and its neighbours: the sub-bin k.
    lp = np.log(p)
    den = lp[j - 1] - 2 * lp[j] + lp[j + 1]
    off = np.where(den < 0, 0.5 * (lp[j - 1] - lp[j + 1]) / np.where(den < 0, den, -1.0), 0.0)
    return _Spectrum(k, k_lo, k_hi, p, k[j] + np.clip(off, -0.5, 0.5) * (k[1] - k[0]))


def _comb_fit(specs: Sequence[_Spectrum], lam: float, rounds: int = 3
              ) -> tuple[float, list[int]]:
    """A comb n / lambda fitted to the peaks from a first guess by least squares on the
    peaks it matches (k_i = n_i / lambda): (lambda, matched peaks per stroke)."""
    dk = min(float(sp.k[1] - sp.k[0]) for sp in specs)
    k_all = np.concatenate([sp.peaks_k for sp in specs])
    for _ in range(rounds):
        n_all = np.rint(k_all * lam)
        good = (n_all >= 1) & (np.abs(k_all - n_all / lam) <= _TOL_BINS * dk)
        if not good.any():
            break
        lam = float(np.sum(n_all[good] ** 2) / np.sum(n_all[good] * k_all[good]))
    hits = []
    for sp in specs:
        n = np.rint(sp.peaks_k * lam)
        hits.append(int(np.sum((n >= 1) & (np.abs(sp.peaks_k - n / lam) <= _TOL_BINS * dk))))
    return lam, hits


def _comb_score(specs: Sequence[_Spectrum], lam: float) -> float:
    """The share of each stroke's in-band spatial power within the comb's teeth less the
    share of the band they cover (what a comb of that density catches of a smooth
    spectrum), averaged over strokes."""
    score = 0.0
    tol = math.ceil(_TOL_BINS)
    for sp in specs:
        step = float(sp.k[1] - sp.k[0])
        i_lo, i_hi = math.ceil(sp.k_lo / step), math.floor(sp.k_hi / step)
        if i_hi - i_lo < 8:
            continue
        harm = np.arange(max(1, math.ceil(sp.k_lo * lam)), math.floor(sp.k_hi * lam) + 1)
        centre = np.rint(harm / lam / step).astype(int)
        i = (centre[:, None] + np.arange(-tol, tol + 1)[None, :]).ravel()
        teeth = np.zeros(sp.k.size, bool)
        teeth[i[(i >= i_lo) & (i <= i_hi)]] = True
        band = slice(i_lo, i_hi + 1)
        p = sp.power[band]
        score += float(p[teeth[band]].sum() / p.sum()) - float(teeth[band].mean())
    return score / len(specs)


@dataclass
class Period:
    """What the period search found: the period, how (``"comb"``; ``"rib"``, a line
    and at most a few harmonics without a comb, :func:`_rib`; ``"given"``), and the
    highest harmonic worth modelling (None: every one in band)."""

    period_mm: float
    kind: str
    harmonics: int | None = None


def estimate_period(strokes: Sequence[_Stroke], f_lo: float, f_hi: float,
                    period_mm: float | None = None) -> Period | None:
    """The spatial period, or None without a comb or a rib. ``period_mm``: a given
    period, refined (within 2 %)."""
    if period_mm is not None:  # given: refined on the coherent power alone
        return Period(_refine(strokes, float(period_mm), f_lo, f_hi, 0.02), "given")
    comb = _comb_period(strokes, f_lo, f_hi)
    return Period(comb, "comb") if comb is not None else _rib(strokes, f_hi)


def _comb_period(strokes: Sequence[_Stroke], f_lo: float, f_hi: float) -> float | None:
    """A comb's period (mm), or None."""
    specs = [sp for st in strokes if (sp := _spatial_spectrum(st, f_lo, f_hi)) is not None]
    if not specs or not any(sp.peaks_k.size for sp in specs):
        return None
    # Guesses: a strong peak as one of the first 12 harmonics, or the spacing of two
    # peaks as one to three harmonics apart.
    candidates: set[float] = set()
    for sp in specs:
        top = sp.peaks_k[:12]
        candidates |= {m / kp for kp in top[:5] for m in range(1, 13)}
        diff = np.abs(top[:, None] - top[None, :])
        candidates |= {d / float(x) for x in diff[diff > 0] for d in (1, 2, 3)}
    candidates = {lam for lam in candidates if 0.05 <= lam <= 50.0}
    if not candidates:
        return None
    # Each guess fitted to the peaks (cheap); the distinct combs with the most matched
    # peaks then scored on the spectra's power.
    fitted: dict[float, tuple[float, list[int]]] = {}
    for guess in sorted(candidates):
        lam, hits = _comb_fit(specs, guess)
        if 0.05 <= lam <= 50.0:
            fitted.setdefault(round(math.log(lam), 4), (lam, hits))
    if not fitted:
        return None
    # Ranked by matches less those a comb that dense would make by chance.
    dk = min(float(sp.k[1] - sp.k[0]) for sp in specs)
    peaks = sum(sp.peaks_k.size for sp in specs)
    top = sorted(fitted.values(),
                 key=lambda t: -(sum(t[1]) - peaks * min(1.0, 2 * _TOL_BINS * dk * t[0])))[:12]
    score, lam, hits = max(((_comb_score(specs, lam), lam, hits) for lam, hits in top),
                           key=lambda t: t[0])
    if score < MIN_COMB_SCORE or np.median(hits) < 3:
        return None
    return _refine(strokes, lam, f_lo, f_hi, 2e-3)


def _rib(strokes: Sequence[_Stroke], f_hi: float) -> Period | None:
    """A rib without a comb: one spatial line, perhaps with a harmonic or two (a
    sinusoidal or rounded rib: corduroy's wale), searched from RIB_F_LO.

    Taken when a spatial frequency k is among the strongest peaks of every stroke whose
    band holds it (the strongest in half of them), in at least RIB_MIN_STROKES strokes
    whose median speeds differ by RIB_MIN_SPEED_RATIO (a fixed tone on strokes at one
    speed stands at one k too; a surface's line moves in f with the speed), and scores
    RIB_MIN_SCORE on those strokes. The fundamental is k / m (m = 3, 2) where every
    stroke that can see k / m has a peak there (the strongest line may be a harmonic);
    the harmonics modelled are those that stand as peaks in at least half the strokes
    that can see them. A rough surface's strongest peaks, where any clear the median
    filter, fall at a different k in every stroke."""
    pairs = [(sp, float(np.median(st.v[st.valid]))) for st in strokes
             if (sp := _spatial_spectrum(st, RIB_F_LO, f_hi)) is not None]
    if not pairs:
        return None
    specs, meds = [p for p, _ in pairs], [m for _, m in pairs]
    tol = _TOL_BINS * min(float(sp.k[1] - sp.k[0]) for sp in specs)

    def seen(k: float) -> list[int]:
        return [i for i, sp in enumerate(specs) if sp.k_lo <= k <= sp.k_hi]

    def rank(i: int, k: float) -> int:  # k's place among stroke i's peaks (99: absent)
        near = np.flatnonzero(np.abs(specs[i].peaks_k - k) <= tol)
        return int(near[0]) if near.size else 99

    def has_peak(i: int, k: float) -> bool:
        return rank(i, k) < 99

    line = None
    for k in (float(sp.peaks_k[0]) for sp in specs if sp.peaks_k.size):
        idx = seen(k)
        ranks = [rank(i, k) for i in idx]
        if (len(idx) >= RIB_MIN_STROKES and max(ranks) < RIB_TOP_PEAKS
                and 2 * ranks.count(0) >= len(idx)
                and max(meds[i] for i in idx) >= RIB_MIN_SPEED_RATIO * min(meds[i] for i in idx)
                and _comb_score([specs[i] for i in idx], 1.0 / k) >= RIB_MIN_SCORE):
            line = k
            break
    if line is None:
        return None
    k0 = line
    for m in (3, 2):  # the strongest line may be the 2nd or 3rd harmonic
        idx = seen(line / m)
        if idx and all(has_peak(i, line / m) for i in idx):
            k0 = line / m
            break
    harmonics = 1
    for n in range(2, 13):
        idx = seen(n * k0)
        if idx and 2 * sum(has_peak(i, n * k0) for i in idx) >= len(idx):
            harmonics = n
    return Period(_refine(strokes, 1.0 / k0, RIB_F_LO, f_hi, 2e-3), "rib", harmonics)


def _refine(strokes: Sequence[_Stroke], lam: float, f_lo: float, f_hi: float,
            span: float) -> float:
    """lambda maximising the coherent power of each stroke's strongest harmonics, within
    +-span (relative), then finer (a parabola through the best three of 21 points).

    At lambda_0 / (1 + eps) harmonic n's phase gains 2 pi n s eps / lambda_0, slow along
    the stroke: the demodulated signal is summed over blocks short enough for that
    phase to stay put, and each eps costs one small matrix product."""
    pieces = []
    for st in strokes:
        a, b = _longest_run(st.valid)
        if b - a < 256:
            continue
        s, y, v = st.s[a:b] - st.s[a], st.y[a:b], st.v[a:b]
        n = np.arange(max(1, math.ceil(f_lo * lam / v.min())),
                      math.floor(f_hi * lam / v.max()) + 1, dtype=float)
        if n.size == 0:
            continue
        if n.size > 24:  # the strongest harmonics carry the fit
            z = np.concatenate([np.abs(y @ _phasors(s, n[c], min(_CHUNK, n.size - c), lam))
                                for c in range(0, n.size, _CHUNK)])
            n = np.sort(n[np.argsort(z)[::-1][:24]])
        pieces.append((s, y, n))
    if not pieces:
        return lam
    # Demodulated once at lambda_0, summed over blocks short enough for the widest span;
    # each level re-centres those sums and regroups them into 64 blocks.
    lam0, first = lam, span
    blocks = []
    for s, y, n in pieces:
        ds = float(s[-1] - s[0]) / max(s.size - 1, 1)
        blk = max(1, int(0.05 * lam0 / (n.max() * max(ds, 1e-12) * first)))
        blk = min(blk, max(1, s.size // 64))  # enough blocks to see the phase ramp
        m = (s.size // blk) * blk
        z = y[:m, None] * np.exp(-2j * np.pi * np.outer(s[:m], n / lam0))
        blocks.append((z.reshape(-1, blk, n.size).sum(axis=1),
                       s[:m].reshape(-1, blk).mean(axis=1), n / lam0, blk * ds))
    centre = 0.0  # lambda = lambda_0 / (1 + eps)
    for _ in range(4):
        grid = np.linspace(-span, span, 21)
        total = np.zeros(grid.size)
        for zb, sb, k, blk_mm in blocks:
            zc = zb * np.exp(-2j * np.pi * centre * np.outer(sb, k))
            # As many blocks per group as this level's span allows, 64 groups at least.
            per = int(0.05 / (k.max() * max(blk_mm, 1e-12) * span))
            per = max(1, min(per, sb.size // 64))
            cut = (sb.size // per) * per
            zc = zc[:cut].reshape(-1, per, k.size).sum(axis=1)
            sc = sb[:cut].reshape(-1, per).mean(axis=1)
            ph = np.exp(-2j * np.pi * np.outer(grid, sc)[:, :, None] * k[None, None])
            total += np.sum(np.abs(np.einsum("gbn,bn->gn", ph, zc)) ** 2, axis=1)
        i = int(np.clip(np.argmax(total), 1, grid.size - 2))
        y0, y1, y2 = total[i - 1], total[i], total[i + 1]
        den = y0 - 2 * y1 + y2
        step = grid[1] - grid[0]
        centre += grid[i] + (0.5 * step * (y0 - y2) / den if den < 0 else 0.0)
        span = 2 * step
    lam = lam0 / (1.0 + centre)
    return lam


K_MAX = 12  # knots of one harmonic's amplitude along speed


@dataclass
class _Harmonics:
    """One stroke's harmonics: each one's complex amplitude, piecewise linear in speed
    over ``knots[n]`` uniform knots from ``lo[n]`` to ``hi[n]`` (0 knots: no data)."""

    lo: Array  # (N,)
    hi: Array  # (N,)
    knots: NDArray[np.int64]  # (N,)
    coef: NDArray[np.complex128]  # (N, K_MAX), the knots' values
    samples: NDArray[np.int64]  # (N,) the fit's samples (those with the harmonic in band)
    ginv: Array  # (N, K_MAX, K_MAX) the inverse normal matrices
    med: float  # the stroke's median speed: the basis is hat(v) (v / med)^2

    def _hats(self, v: Array, sl: slice) -> tuple[NDArray[np.int64], Array]:
        """(lower knot index, weight of the upper) of each speed for each harmonic."""
        lo, hi, k = self.lo[sl], self.hi[sl], self.knots[sl]
        span = np.where(hi > lo, hi - lo, 1.0)
        top = np.maximum(k - 1, 0).astype(float)
        x = np.clip((v[:, None] - lo[None, :]) / span[None, :] * top[None, :], 0.0,
                    top[None, :])
        i0 = np.minimum(x.astype(np.int64), np.maximum(k - 2, 0)[None, :])
        return i0, x - i0

    def at(self, v: Array, first: int = 0, count: int | None = None
           ) -> NDArray[np.complex128]:
        """Complex amplitudes (len(v), count) of harmonics first.. at speeds v (the edge
        knots' values beyond)."""
        sl = slice(first, None if count is None else first + count)
        i0, w = self._hats(v, sl)
        c = self.coef[sl]
        rows = np.arange(c.shape[0])[None, :]
        out = (1 - w) * c[rows, i0] + w * c[rows, np.minimum(i0 + 1, K_MAX - 1)]
        out *= ((v / self.med) ** 2)[:, None]
        return np.where((self.knots[sl] > 0)[None, :], out, 0.0)

    def noise_gain(self, v: Array) -> Array:
        """b(v)^T G^-1 b(v) (len(v), N): the fit's variance at v per unit of noise (b the
        hat weights at v, G the normal matrix): large where the stroke had few samples."""
        i0, w = self._hats(v, slice(None))
        rows = np.arange(self.knots.size)[None, :]
        i1 = np.minimum(i0 + 1, K_MAX - 1)
        g = self.ginv
        return ((1 - w) ** 2 * g[rows, i0, i0] + 2 * w * (1 - w) * g[rows, i0, i1]
                + w ** 2 * g[rows, i1, i1]) * ((v / self.med) ** 4)[:, None]


def _phasors(s: Array, n0: float, count: int, lam: float) -> NDArray[np.complex128]:
    """exp(-j 2 pi n s / lambda) for n = n0, n0 + 1, ..: (len(s), count), by a running
    product of the first harmonic's phasor (cheaper than exp; exact to ~count x 1e-16)."""
    e1 = np.exp(-2j * np.pi * s / lam)
    out = np.empty((s.size, count), complex)
    out[:, 0] = np.exp(-2j * np.pi * n0 * s / lam)
    for j in range(1, count):
        np.multiply(out[:, j - 1], e1, out=out[:, j])
    return out


def _speed_bins(v: Array) -> tuple[NDArray[np.int64], Array, NDArray[np.int64]]:
    """Samples grouped by speed in FINE_MM_S bins: (each sample's bin, the bins' mean
    speeds, their counts); empty bins dropped, so the speeds ascend."""
    raw = ((v - float(v.min())) / FINE_MM_S).astype(np.int64)
    used, b = np.unique(raw, return_inverse=True)
    cnt = np.bincount(b, minlength=used.size)
    return b, np.bincount(b, v, used.size) / cnt, cnt


def _fit_stroke(st: _Stroke, lam: float, n_max: int, f_top: float, knot_hz: float
                ) -> tuple[_Harmonics, Array]:
    """Per harmonic n = 1..n_max, its complex amplitude as a function of
    speed by least squares: (v / med)^2 (an acceleration's v^2) times a piecewise linear
    function between knots spaced so that the harmonic's frequency moves ``knot_hz`` from
    one to the next (the scale on which a tool's resonance changes it), 3 to K_MAX knots
    over the stroke's speeds.

    y ~ Re{c(v) e^{j theta}} with theta = 2 pi n s / lambda: the demodulated
    y e^{-j theta} ~ c(v) / 2 + terms at 2 theta, which average out over many periods, so
    each harmonic is a small real-basis least squares on it (a tridiagonal system). The
    basis is a function of speed alone: the demodulated samples are summed per
    FINE_MM_S speed bin first (one sparse product), and each harmonic's system is built
    on the bins. Also returns every fitted harmonic summed over the valid samples (what
    the noise estimate subtracts), made with the same phasors."""
    idx = np.flatnonzero(st.valid)
    v, y, s = st.v[idx], st.y[idx], st.s[idx]
    bins, vb, cnt = _speed_bins(v)
    total = np.cumsum(cnt)
    summing = sparse.csr_matrix((np.ones(v.size), (bins, np.arange(v.size))),
                                shape=(vb.size, v.size))
    grow = (vb / st.med) ** 2  # an acceleration's lines grow as v^2
    lo_all, hi_all = np.zeros(n_max), np.zeros(n_max)
    kn_all = np.zeros(n_max, np.int64)
    m_all = np.zeros(n_max, np.int64)
    coef = np.zeros((n_max, K_MAX), complex)
    ginv = np.zeros((n_max, K_MAX, K_MAX))
    phasors = []  # kept for the fitted lines' sum below
    for c0 in range(0, n_max, _CHUNK):
        c_n = min(_CHUNK, n_max - c0)
        n = np.arange(c0, c0 + c_n) + 1.0
        ph = _phasors(s, n[0], c_n, lam)
        phasors.append(ph)
        zb = summing @ (ph * y[:, None])  # (bins, c) sums
        for j in range(c_n):
            nb_in = int(np.searchsorted(vb, f_top * lam / n[j], side="right"))  # in band
            m = int(total[nb_in - 1]) if nb_in else 0
            if m < 64:
                continue
            # The knots span all but the sparse 1 % tails of the speeds (clamped beyond):
            # a knot out there would rest on a handful of samples.
            q_lo = int(np.searchsorted(total, m // 100, side="right"))
            q_hi = int(np.searchsorted(total, m - m // 100, side="left"))
            lo, hi = float(vb[min(q_lo, nb_in - 1)]), float(vb[min(q_hi, nb_in - 1)])
            k = (int(np.clip(1 + math.ceil((hi - lo) * n[j] / lam / knot_hz), 3, K_MAX))
                 if hi > lo else 1)
            w_cnt, zj, gj = cnt[:nb_in], zb[:nb_in, j], grow[:nb_in]
            if k > 1:
                x = np.clip((vb[:nb_in] - lo) / (hi - lo) * (k - 1), 0.0, k - 1 - 1e-9)
                i0 = x.astype(np.int64)
                w1 = (x - i0) * gj
                w0 = (1 - (x - i0)) * gj
                # Normal equations of the hat basis: a tridiagonal G, right side B^T z.
                diag = (np.bincount(i0, w_cnt * w0 * w0, k)
                        + np.bincount(i0 + 1, w_cnt * w1 * w1, k))
                off = np.bincount(i0, w_cnt * w0 * w1, k)[:-1]
                g = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
                g += np.eye(k) * 1e-6 * diag.sum() / k  # a knot with little data near it
                rhs = (np.bincount(i0, w0 * zj.real, k) + np.bincount(i0 + 1, w1 * zj.real, k)
                       + 1j * (np.bincount(i0, w0 * zj.imag, k)
                               + np.bincount(i0 + 1, w1 * zj.imag, k)))
                gi = np.linalg.inv(g)
                c = 2.0 * (gi @ rhs)
            else:
                gi = np.array([[1.0 / float(np.dot(w_cnt * gj, gj))]])
                c = np.array([2.0 * complex(np.dot(gj, zj)) * gi[0, 0]])
            ginv[c0 + j, :k, :k] = gi
            lo_all[c0 + j], hi_all[c0 + j], kn_all[c0 + j], m_all[c0 + j] = lo, hi, k, m
            coef[c0 + j, :k] = c
            coef[c0 + j, k:] = c[-1]
    fit = _Harmonics(lo_all, hi_all, kn_all, coef, m_all, ginv, st.med)
    line = np.zeros(v.size)
    for c0, ph in zip(range(0, n_max, _CHUNK), phasors, strict=True):
        c_n = ph.shape[1]
        inband = np.outer(vb, (np.arange(c0, c0 + c_n) + 1.0) / lam) <= f_top
        amp = fit.at(vb, c0, c_n) * inband
        line += np.sum(np.real(amp[bins] * np.conj(ph)), axis=1)
    return fit, line


def _spread(values: Array, has: Mask) -> Array:
    """Each row without data takes the nearest row with data (index along axis 0)."""
    out = values.copy()
    j = np.flatnonzero(has)
    if j.size == 0:
        return out
    near = j[np.argmin(np.abs(np.arange(values.shape[0])[:, None] - j[None, :]), axis=1)]
    return out[near]


def _factor_model(power: Array, present: Mask, grid: Array, lam: float, fs_hz: float,
                  smooth: float = 1.0) -> Array:
    """log P_n(v) ~ u_n + t(n v / lambda) + g(v), the two-part picture of a periodic
    surface seen through a tool (docs/texture.md): a level per harmonic (the surface's
    shape), a function of frequency (the tool's response, piecewise linear every 10 Hz)
    and one of speed (the drive, one value per grid row), fitted by least squares to the
    log power of the harmonics present, second differences of t and g penalised; g across
    rows where no harmonic is present is linear in log speed between the rows where one
    is. Returns exp of the fit at every (row, harmonic)."""
    nb, n_h = power.shape
    rows, harm = np.nonzero(present & (power > 0))
    if rows.size == 0:
        return np.zeros_like(power)
    f_knots = np.arange(0.0, fs_hz / 2 + 10.0, 10.0)
    nf = f_knots.size
    freq = grid[rows] * (harm + 1) / lam
    x = np.clip(freq / 10.0, 0.0, nf - 1 - 1e-9)
    i0 = x.astype(int)
    w1 = x - i0
    m = rows.size
    r = np.arange(m)
    # Columns: u (n_h), t (nf), g (nb).
    a = sparse.csr_matrix((np.concatenate([np.ones(m), 1 - w1, w1, np.ones(m)]),
                       (np.concatenate([r, r, r, r]),
                        np.concatenate([harm, n_h + i0, n_h + i0 + 1, n_h + nf + rows]))),
                      shape=(m, n_h + nf + nb))

    def second_diff(k: int, start: int) -> sparse.csr_matrix:
        if k < 3:  # a one- or two-row speed grid (a constant-speed rig): nothing to bend
            return sparse.csr_matrix((0, n_h + nf + nb))
        d = sparse.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(k - 2, k))
        return sparse.hstack([sparse.csr_matrix((d.shape[0], start)), d,
                          sparse.csr_matrix((d.shape[0], n_h + nf + nb - start - k))])

    pen = sparse.vstack([second_diff(nf, n_h), second_diff(nb, n_h + nf)])
    lhs = (a.T @ a + smooth * m / max(pen.shape[0], 1) * (pen.T @ pen)
           + 1e-6 * sparse.identity(n_h + nf + nb)).tocsc()
    sol = spla.spsolve(lhs, a.T @ np.log(power[rows, harm]))
    u, t, g = sol[:n_h], sol[n_h:n_h + nf], sol[n_h + nf:]
    # Across a gap between rows with lines (no stroke went there, or its lines were under
    # the noise), g is a power law (linear in log speed) between its ends: the penalty
    # alone bends it by the slopes it has at them (R1 at 15 mm/s, between strokes at 10
    # and 20: +2 dB on every line).
    have = np.unique(rows)
    gap = np.setdiff1d(np.arange(have[0] + 1, have[-1]), have)
    g = g.copy()
    g[gap] = np.interp(np.log(grid[gap]), np.log(grid[have]), g[have])
    f_all = np.outer(grid, np.arange(1, n_h + 1) / lam)
    return np.exp(u[None, :] + np.interp(f_all, f_knots, t) + g[:, None])


def _fill(power: Array, present: Mask, data: Mask, model: Array) -> Array:
    """One harmonic's power at every grid row. Rows with data: the measured line (0 where
    it was below the noise). Rows without: the factor model times its error at the
    nearest rows with the line (interpolated between two), going linearly to 0 towards a
    row with data and no line; 0 if the harmonic has no line anywhere, or at only one
    row that has a neighbour with data (a stroke's fastest or slowest instants: see
    :func:`_carries_over`)."""
    out = np.where(data, power, 0.0)
    if not _carries_over(present, data):
        return out
    x = np.arange(power.size, dtype=float)
    rows = np.flatnonzero(present)
    err = np.interp(x, rows, np.log(power[rows] / model[rows]))
    pred = model * np.exp(err)
    drows = np.flatnonzero(data)
    nxt = np.searchsorted(drows, x)  # the first row with data at or after each row
    for i in np.flatnonzero(~data):
        j = nxt[i]
        left = drows[j - 1] if j > 0 else None
        right = drows[j] if j < drows.size else None
        on_l = left is not None and present[left]
        on_r = right is not None and present[right]
        if (left is None or on_l) and (right is None or on_r):
            out[i] = pred[i]
        elif on_l or on_r:  # between a row with the line and one without: fade
            w = (i - left) / (right - left)
            out[i] = pred[i] * ((1 - w) if on_l else w)
    return out


def _carries_over(present: Mask, data: Mask) -> bool:
    """Whether a harmonic's line may be carried into rows without data: seen at two rows
    or more, or at one row that is data alone (a constant-speed rig's speed). One row at
    the edge of a run of data is a stroke's few fastest or slowest instants: noise over
    the threshold there (canvas: harmonics 26 and 31 seen only at 11.5 mm/s, the 10 mm/s
    strokes' top, 20 dB over what the recordings hold) was carried by the factor model
    across the 12-17 mm/s gap and grew 15 dB on the way (+3.1 dB LSD at 15 mm/s)."""
    rows = np.flatnonzero(present)
    if rows.size != 1:
        return rows.size > 1
    r = int(rows[0])
    return not ((r > 0 and data[r - 1]) or (r + 1 < data.size and data[r + 1]))


def _lines(st: _Stroke, fit: _Harmonics, use_at: Mask, grid: Array, lam: float,
           f_top: float) -> Array:
    """The stroke's fitted harmonics summed over its valid samples, each where
    ``use_at[grid row of the sample's speed, n]`` and in band."""
    idx = np.flatnonzero(st.valid)
    vv, ss_ = st.v[idx], st.s[idx]
    nb, n_max = use_at.shape
    # Amplitudes at the speed bins' speeds, then per sample (a function of speed alone).
    bins, vb, _ = _speed_bins(vv)
    row = np.clip(np.rint((vb - grid[0]) / GRID_STEP_MM_S).astype(int), 0, nb - 1)
    line = np.zeros(idx.size)
    for c0 in range(0, n_max, _CHUNK):
        cnt = min(_CHUNK, n_max - c0)
        n = np.arange(c0, c0 + cnt) + 1.0
        amp = fit.at(vb, c0, cnt) * (use_at[row, c0:c0 + cnt]
                                      & (np.outer(vb, n / lam) <= f_top))
        line += np.sum(np.real(amp[bins] * np.conj(_phasors(ss_, n[0], cnt, lam))), axis=1)
    return line


def _noise_of_fit(rest: Array, fit: _Harmonics, lam: float, fs_hz: float):
    """v -> (len(v), N): the E|c(v)|^2 that noise alone gives harmonic n's fit at v.

    With the demodulated noise's slow part at half the one-sided spectrum P(f) of the
    signal near the harmonic, the least-squares fit c = 2 G^-1 B^T z has
    E|c(v)|^2 = 2 P(f) fs b(v)^T G^-1 b(v) (a constant fit over T seconds: 2 P / T). P is
    the Welch spectrum of ``rest`` (what every harmonic's fit leaves), median-smoothed
    over 5 bins so a line left in it does not count as noise."""
    nper = int(min(256, rest.size))
    f, p = ss.welch(rest, fs_hz, nperseg=nper)
    p = ndi.median_filter(p, size=5, mode="nearest")
    n = np.arange(1, fit.knots.size + 1)

    def q_of(v: Array) -> Array:
        pf = np.interp(np.outer(v, n / lam), f, p)
        return 2.0 * pf * fs_hz * fit.noise_gain(v)

    return q_of


def fit_lines(signals: Sequence[Array], speeds: Sequence[Array], fs_hz: float,
              speed_range: tuple[float, float], *, period_mm: float | None = None
              ) -> LineFit:
    """The line spectrum of preprocessed strokes (see the module docstring).

    ``speed_range``: the modelled speeds (mm/s); ``period_mm``: a known period (refined
    within 2 %; the lines are then kept whatever their share). Without a periodic part
    (or one below ``MIN_SHARE`` of the power) the residuals are the signals and every
    sample may be used.
    """
    snr, min_share, knot_hz = DEFAULT_SNR, MIN_SHARE, KNOT_HZ
    signals = [np.asarray(y, float) for y in signals]
    speeds = [np.asarray(v, float) for v in speeds]
    whole = LineFit.none(signals, "")
    f_top = BAND_TOP * fs_hz / 2
    f_lo = 15.0  # above the 10 Hz high-pass's knee
    strokes = []
    for i, (y, v) in enumerate(zip(signals, speeds, strict=True)):
        span = _stroke_span(v, speed_range, fs_hz)
        if span is not None and span[1].sum() >= 0.5 * fs_hz:
            strokes.append(_Stroke(i, y, v, arc_length_mm(v, fs_hz), span[0], span[1]))
    if not strokes:
        whole.note = "no stroke holds 0.5 s within the modelled speeds"
        return whole
    found = estimate_period(strokes, f_lo, f_top, period_mm)
    if found is None:
        whole.note = ("no spatial period (no harmonic comb stands out of the spectrum, nor "
                      "a rib's line in every stroke whose band holds it)")
        return whole
    lam = found.period_mm
    n_max = int(max(math.floor(f_top * lam / float(st.v[st.valid].min())) for st in strokes))
    if found.harmonics is not None:
        # A rib: only the harmonics that stood as spatial peaks. Every harmonic in band,
        # kept at the noise rule's odds (a few cells per thousand over every harmonic
        # and row), gave corduroy 47 narrow lines of noise, and its held-out strokes
        # scored 0.04-0.11 dB better with its one line alone.
        n_max = min(n_max, found.harmonics)
    capped = n_max > MAX_HARMONICS
    n_max = min(n_max, MAX_HARMONICS)
    if n_max < 1:
        whole.note = f"period {lam:.4g} mm: no harmonic within the band"
        return whole
    grid = np.arange(math.floor(speed_range[0] / GRID_STEP_MM_S) * GRID_STEP_MM_S,
                     speed_range[1] + GRID_STEP_MM_S / 2, GRID_STEP_MM_S)
    grid = grid[grid > 0]
    nb = grid.size
    p_sum = np.zeros((nb, n_max))
    q_sum = np.zeros((nb, n_max))
    w_sum = np.zeros((nb, n_max))
    fitted = [_fit_stroke(st, lam, n_max, f_top, knot_hz) for st in strokes]
    fits = [f for f, _ in fitted]
    strong = np.zeros((nb, n_max), bool)
    for st, (fit, every_line) in zip(strokes, fitted, strict=True):
        # What a fit of this many knots catches of the noise alone: from the spectrum of
        # what every harmonic's fit leaves (module docstring, step 3).
        q_of = _noise_of_fit(st.y[st.valid] - every_line, fit, lam, fs_hz)
        vv = st.v[st.valid]
        b = np.clip(np.rint((vv - grid[0]) / GRID_STEP_MM_S).astype(int), 0, nb - 1)
        cnt = np.bincount(b, minlength=nb).astype(float)
        rows = np.flatnonzero(cnt)
        inband = np.outer(grid[rows], np.arange(1, n_max + 1) / lam) <= f_top
        w = cnt[rows, None] * inband * (fit.knots > 0)[None, :]
        p_rows, q_rows = np.abs(fit.at(grid[rows])) ** 2, q_of(grid[rows])
        p_sum[rows] += w * p_rows
        q_sum[rows] += w * q_rows
        w_sum[rows] += w
        # A stroke whose own fit stands far out at a row makes the line present there
        # whatever the pool's mean says (a speed few strokes reached); not at the pool's
        # threshold: many weak harmonics over many rows would keep noise as lines.
        strong[rows] |= (w > 0) & (p_rows > OWN_SNR_FACTOR * snr * q_rows)
    data = w_sum >= MIN_BIN_S * fs_hz
    with np.errstate(invalid="ignore", divide="ignore"):
        p_mean = np.where(data, p_sum / w_sum, 0.0)
        q_mean = np.where(data, q_sum / w_sum, 0.0)
    present = data & ((p_mean > snr * q_mean) | strong)
    # A line persists from one 0.5 mm/s row to the next; noise over the threshold does not
    # (a few cells in a thousand at snr 3): a row counts unless every neighbour with data
    # disagrees (a row whose neighbours have no data stands on its own: a constant-speed
    # rig, the fastest instants of a stroke).
    agree = np.zeros_like(present)
    agree[1:] |= present[:-1] | ~data[:-1]
    agree[:-1] |= present[1:] | ~data[1:]
    agree[[0, -1]] |= True if nb == 1 else False
    present &= agree
    # Amplitude^2 of the line alone; where only one stroke's fit made it present, the
    # pool's mean over strokes may not clear the noise's: at least a quarter of the mean.
    power = np.where(present, np.maximum(p_mean - q_mean, 0.25 * p_mean), 0.0)
    present &= power > 0
    # Each harmonic's rows: the table from its rows with data (interpolated per column).
    model = _factor_model(power, present, grid, lam, fs_hz)
    table = np.zeros_like(power)
    for n in range(n_max):
        table[:, n] = _fill(power[:, n], present[:, n], data[:, n], model[:, n])
    # A row is mixed in up to the next row's speed: its harmonics must stay in band there.
    freq = np.outer(grid + GRID_STEP_MM_S, np.arange(1, n_max + 1) / lam)
    taper = np.clip((BAND_TOP * fs_hz / 2 - freq) / ((BAND_TOP - TAPER_START) * fs_hz / 2),
                    0.0, 1.0)
    amplitude = np.sqrt(table) * (0.5 - 0.5 * np.cos(np.pi * taper))
    # Subtraction: a harmonic is removed where its nearest row with data keeps it.
    keep_near = np.zeros((nb, n_max), bool)
    for n in range(n_max):
        keep_near[:, n] = _spread(present[:, n].astype(float), data[:, n]) > 0.5
    # Up to where the table's taper starts: above it a stroke's fit over-states its
    # harmonics (the decimation filter's roll-off moves across a harmonic's speed range
    # faster than its knots), and taking them out left the residual up to 6 dB over the
    # signal at 470-500 Hz (R1 at 40 mm/s: +2 dB at 450-500 Hz rendered).
    f_sub = TAPER_START * fs_hz / 2
    residuals = list(signals)  # a stroke without a line fit: none of it is clean
    keeps = [np.zeros(y.size, bool) for y in signals]
    line_energy = total_energy = 0.0
    for st, fit in zip(strokes, fits, strict=True):
        idx = np.flatnonzero(st.valid)
        r = st.y.copy()
        r[idx] -= _lines(st, fit, keep_near, grid, lam, f_sub)
        residuals[st.index] = r
        keeps[st.index] = st.valid.copy()
        line_energy += float(np.dot(st.y[idx], st.y[idx]) - np.dot(r[idx], r[idx]))
        total_energy += float(np.dot(st.y[idx], st.y[idx]))
    share = line_energy / total_energy if total_energy > 0 else 0.0
    if not present.any():
        whole.note = f"period {lam:.4g} mm: no harmonic stands over the noise"
        whole.period_mm = lam
        return whole
    if period_mm is None and share < min_share:
        whole.note = (f"period {lam:.4g} mm: its lines hold {100 * share:.1f} % of the power "
                      f"(< {100 * min_share:g} %): left to the all-pole model")
        whole.period_mm = lam
        whole.share = share
        return whole
    ref = min(range(len(strokes)), key=lambda i: (strokes[i].med, -strokes[i].valid.sum()))
    phase = np.angle(fits[ref].at(np.array([strokes[ref].med]))[0])
    spectrum = LineSpectrum(lam, grid, amplitude, phase)
    kept = int(np.sum(present.any(axis=0)))
    if found.kind == "rib":
        what = ("a rib: one line" if kept == 1 else f"a rib: {kept} harmonics") + ", no comb"
    else:
        what = f"{kept} harmonics kept"
    note = (f"period {lam:.4f} mm, {what}, {100 * share:.1f} % of the power in "
            + ("the line" if kept == 1 else "lines"))
    if capped:
        note += (f"; harmonics above the {MAX_HARMONICS}th (in band only at the slowest "
                 "speeds) are left to the all-pole model")
    if period_mm is not None and share < min_share:
        note += (f"; only {100 * share:.1f} % of the power at the given period: check it "
                 "(it is refined within about 2 %)")
    return LineFit(spectrum, residuals, keeps, lam, share, note)
