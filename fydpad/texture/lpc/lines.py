"""Periodic surfaces: the harmonics of a spatial period, following the finger.

A grating, mesh, weave or knurl puts lines at n v / lambda that move with the speed v;
an all-pole fit per speed pools the hand's wander and smears them into bands. Here they
are deterministic in the position s along the stroke, beside the paper's eq. 5 process
(fitted on what they leave):

    a_lines(t) = sum_n A_n(v(t)) cos(2 pi n s(t) / lambda + psi_n),   s(t) = int v dt

:func:`fit_lines`, on each stroke's preprocessed (high-passed, DFT321) signal:

1. The period: on the arc-length resampled spectra, the comb n / lambda that puts peaks
   on the most harmonics, refined to 1e-5 on its strongest harmonics' coherent power;
   without a comb, a rib: one line that is the strongest peak of every stroke able to
   see it (corduroy's wale, :func:`_rib`).
2. Per stroke and harmonic, the complex amplitude as (v / med)^2 times a piecewise linear
   function of speed, by least squares on the signal demodulated at 2 pi n s / lambda.
3. Per 0.5 mm/s speed bin, pooled over strokes: amplitude^2 less what noise alone gives
   the fit; kept where ``DEFAULT_SNR`` times over it. Speeds no stroke reached: a factor
   model log P_n(v) = u_n + t(n v / lambda) + g(v) (:func:`_factor_model`).
4. The residual: each stroke less its kept harmonics, on the samples within +-45 % of its
   median speed (only those go to the stochastic fit).

The phases psi_n are the slowest stroke's (every harmonic in band there): they give the
waveform its shape, not its spectrum.
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
#: Nor those where the speed changes faster than this (relative, per second: a hand's
#: sway 0.5 /s at most, a stroke's start 3 /s and more), within EDGE_S of it or of an end.
MAX_SPEED_RATE = 1.5
EDGE_S = 0.25
#: Speed grid of the amplitude table (mm/s).
GRID_STEP_MM_S = 0.5
#: A rib is searched from under the 10 Hz high-pass's corner (a 2.5 mm rib at 25 mm/s
#: is at 10 Hz), in RIB_MIN_STROKES strokes or more whose median speeds span
#: RIB_MIN_SPEED_RATIO (a hum on a constant-speed rig stands at one k in every stroke),
#: among the RIB_TOP_PEAKS strongest peaks of each, holding RIB_MIN_SCORE (_comb_score)
#: of their spatial power (a rib on a rough surface, 0.003 mm RMS, scored 0.10).
RIB_F_LO = 8.0
RIB_MIN_STROKES = 2
RIB_MIN_SPEED_RATIO = 1.2
RIB_TOP_PEAKS = 3
RIB_MIN_SCORE = 0.1
#: Harmonics up to this fraction of Nyquist (the scans' anti-alias filter ends there),
#: tapered from TAPER_START so that none drops out with a click.
BAND_TOP = 0.99
TAPER_START = 0.96
#: A kept harmonic's pooled power over what noise alone gives its fit; or one stroke's
#: own fit OWN_SNR_FACTOR times over that.
DEFAULT_SNR = 3.0
OWN_SNR_FACTOR = 4.0
#: Less of the power than this in the lines: no line model (the all-pole model holds
#: such weak lines as well).
MIN_SHARE = 0.05
#: Seconds of data (pooled) a speed bin needs to say something about a harmonic.
MIN_BIN_S = 0.25
#: The comb's teeth must hold this much more of the spatial power than their share of
#: the band (a smooth spectrum: 0).
MIN_COMB_SCORE = 0.2
#: Harmonics modelled at most (the wavetable then has 32 points per cycle of the highest).
MAX_HARMONICS = 512
#: Knot spacing of a harmonic's amplitude along speed, in Hz of its frequency: the scale
#: on which a tool resonance changes it (a mode of Q 10 at 300 Hz is 30 Hz wide).
KNOT_HZ = 20.0
K_MAX = 12  # knots of one harmonic's amplitude at most
#: Speed bins of the per-harmonic fits (mm/s): the amplitudes change over 1 mm/s or more.
FINE_MM_S = 0.01
_CHUNK = 64  # harmonics per matrix product (memory: samples x chunk complex)
_PAD = 2  # zero padding of the spatial periodogram
_TOL_BINS = 1.5 * _PAD  # a peak matches a harmonic within this many padded bins


@dataclass
class LineSpectrum:
    """Harmonic amplitudes of a period over a speed grid (the model file's ``lines``)."""

    period_mm: float
    v_mm_s: Array  # (m,) ascending, GRID_STEP_MM_S apart
    amplitude: Array  # (m, N) peak amplitude of harmonic n = 1..N, m/s^2
    phase_rad: Array  # (N,)

    def wavetable(self) -> Array:
        """One period of the waveform at every grid speed, (m, points + 1), the last
        column repeating the first; 32 points per cycle of the highest harmonic."""
        top = int(np.max(np.nonzero(self.amplitude.any(axis=0))[0], initial=-1)) + 1
        points = int(min(max(256, 2 ** math.ceil(math.log2(max(32 * top, 1)))), 16384))
        spec = np.zeros((self.v_mm_s.size, points // 2 + 1), complex)
        m = min(self.amplitude.shape[1], points // 2 - 1)
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

        def bad(key: str, what: str) -> UserError:
            return UserError(f"{where}: key 'lines.{key}' must {what}")

        def arr(key: str, ndim: int) -> Array:
            if key not in d:
                raise UserError(f"{where}: missing key 'lines.{key}'")
            try:
                a = np.asarray(d[key], float)
            except (TypeError, ValueError):
                raise bad(key, "be numbers") from None
            if a.ndim != ndim or a.size == 0 or not np.all(np.isfinite(a)):
                raise bad(key, f"be a non-empty {'list' if ndim == 1 else 'table'} of "
                          "finite numbers")
            return a

        period = d.get("period_mm")
        if isinstance(period, bool) or not isinstance(period, int | float) or not (
                math.isfinite(period) and period > 0):
            raise bad("period_mm", f"be a number > 0, not {period!r}")
        if period < 1e-3 or period > 1e3:
            raise bad("period_mm", f"be within 0.001-1000 mm, not {period!r}")
        v, phase, amp = arr("v_mm_s", 1), arr("phase_rad", 1), arr("amplitude", 2)
        step = np.diff(v)
        if (v[0] < 0 or v[-1] > 1e4 or np.any(step < 0.01)
                or (step.size and np.any(np.abs(step - step[0]) > 1e-6 * step[0]))):
            raise bad("v_mm_s", "be speeds 0-10000 mm/s, ascending in equal steps of at "
                      "least 0.01 mm/s")
        if amp.shape != (v.size, phase.size):
            raise bad("amplitude", f"have one row per 'lines.v_mm_s' ({v.size}) and one "
                      f"column per 'lines.phase_rad' ({phase.size}), not {amp.shape[0]} x "
                      f"{amp.shape[1]}")
        if np.any(amp < 0):
            raise bad("amplitude", "be >= 0")
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


@dataclass
class _Stroke:
    index: int  # of the signal it comes from
    y: Array
    v: Array
    s: Array  # arc length, mm
    med: float
    valid: Mask  # the samples that carry the line fit
    run: slice | None  # the longest run of them, if 256 samples or more


def _stroke(i: int, y: Array, v: Array, speed_range: tuple[float, float], fs_hz: float
            ) -> _Stroke | None:
    """The stroke's samples within SPEED_SPAN of its median speed and the range, not
    within EDGE_S of a change faster than MAX_SPEED_RATE (the tool's resonance does not
    follow such a sweep, and DFT321 smears it) nor of its ends; None under 0.5 s."""
    lo, hi = speed_range
    inr = (v >= lo) & (v <= hi) & (v > 0)
    if inr.sum() < 16:
        return None
    med = float(np.median(v[inr]))
    fast = np.abs(np.gradient(v) * fs_hz) > MAX_SPEED_RATE * np.maximum(v, 1.0)
    guard = max(1, round(EDGE_S * fs_hz))
    fast = ndi.binary_dilation(fast, np.ones(2 * guard + 1, bool))
    fast[:guard] = fast[-guard:] = True
    valid = inr & ~fast & (np.abs(v - med) < SPEED_SPAN * med)
    if valid.sum() < 0.5 * fs_hz:
        return None
    a, b = max(runs(valid), key=lambda r: r[1] - r[0], default=(0, 0))
    return _Stroke(i, y, v, arc_length_mm(v, fs_hz), med, valid,
                   slice(a, b) if b - a >= 256 else None)


@dataclass
class _Spectrum:
    """A stroke's spatial periodogram and its peaks (sub-bin interpolated)."""

    k: Array  # cycles/mm
    k_lo: float  # the harmonics' band for every sample of the run
    k_hi: float
    power: Array
    peaks_k: Array  # strongest first


def _spatial_spectrum(st: _Stroke, f_lo: float, f_hi: float) -> _Spectrum | None:
    """Hann periodogram of the stroke's longest valid run on a uniform arc-length grid,
    where the harmonics stand at n / lambda whatever the speed."""
    if st.run is None:
        return None
    s, y, v = st.s[st.run], st.y[st.run], st.v[st.run]
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


def _comb_fit(specs: Sequence[_Spectrum], lam: float) -> tuple[float, list[int]]:
    """A comb k_i = n_i / lambda fitted by least squares on the peaks it matches, three
    rounds from a guess: (lambda, matched peaks per stroke)."""
    dk = min(float(sp.k[1] - sp.k[0]) for sp in specs)
    k_all = np.concatenate([sp.peaks_k for sp in specs])
    for _ in range(3):
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
    share of the band they cover, averaged over strokes."""
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
    fitted: dict[float, tuple[float, list[int]]] = {}
    for guess in sorted(lam for lam in candidates if 0.05 <= lam <= 50.0):
        lam, hits = _comb_fit(specs, guess)
        if 0.05 <= lam <= 50.0:
            fitted.setdefault(round(math.log(lam), 4), (lam, hits))
    if not fitted:
        return None
    # The 12 with the most matches less those a comb that dense makes by chance, scored
    # on the spectra's power.
    dk = min(float(sp.k[1] - sp.k[0]) for sp in specs)
    peaks = sum(sp.peaks_k.size for sp in specs)
    top = sorted(fitted.values(),
                 key=lambda t: -(sum(t[1]) - peaks * min(1.0, 2 * _TOL_BINS * dk * t[0])))[:12]
    score, lam, hits = max(((_comb_score(specs, lam), lam, hits) for lam, hits in top),
                           key=lambda t: t[0])
    if score < MIN_COMB_SCORE or np.median(hits) < 3:
        return None
    return _refine(strokes, lam, f_lo, f_hi, 2e-3)


def _rib(strokes: Sequence[_Stroke], f_hi: float) -> tuple[float, int] | None:
    """A rib without a comb: (period, highest harmonic modelled), or None.

    Its line k is among the RIB_TOP_PEAKS strongest peaks of every stroke whose band
    holds it (the strongest in half of them: a rounded rib's 2nd harmonic may outdo it);
    the fundamental is k / 3 or k / 2 where every stroke that can see it has a peak
    there; harmonics up to the 12th count where half the strokes that can see them have
    a peak. A rough surface's strongest peaks fall at a different k in every stroke."""
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

    for line in (float(sp.peaks_k[0]) for sp in specs if sp.peaks_k.size):
        idx = seen(line)
        ranks = [rank(i, line) for i in idx]
        if (len(idx) >= RIB_MIN_STROKES and max(ranks) < RIB_TOP_PEAKS
                and 2 * ranks.count(0) >= len(idx)
                and max(meds[i] for i in idx) >= RIB_MIN_SPEED_RATIO * min(meds[i] for i in idx)
                and _comb_score([specs[i] for i in idx], 1.0 / line) >= RIB_MIN_SCORE):
            break
    else:
        return None
    k0 = line
    for m in (3, 2):
        idx = seen(line / m)
        if idx and all(rank(i, line / m) < 99 for i in idx):
            k0 = line / m
            break
    harmonics = 1
    for n in range(2, 13):
        idx = seen(n * k0)
        if idx and 2 * sum(rank(i, n * k0) < 99 for i in idx) >= len(idx):
            harmonics = n
    return _refine(strokes, 1.0 / k0, RIB_F_LO, f_hi, 2e-3), harmonics


def _refine(strokes: Sequence[_Stroke], lam: float, f_lo: float, f_hi: float,
            span: float) -> float:
    """lambda maximising the coherent power of each stroke's 24 strongest harmonics
    within +-span (relative), four levels of 21 points and a parabola.

    At lambda_0 / (1 + eps) harmonic n's phase gains 2 pi n s eps / lambda_0, slowly
    along the stroke: the demodulated signal is summed over blocks short enough for that
    phase to stay put, and each eps costs one small matrix product."""
    blocks = []  # demodulated once, summed over blocks short enough for the span
    for st in strokes:
        if st.run is None:
            continue
        s, y, v = st.s[st.run] - st.s[st.run.start], st.y[st.run], st.v[st.run]
        n = np.arange(max(1, math.ceil(f_lo * lam / v.min())),
                      math.floor(f_hi * lam / v.max()) + 1, dtype=float)
        if n.size == 0:
            continue
        if n.size > 24:
            z = np.concatenate([np.abs(y @ _phasors(s, n[c], min(_CHUNK, n.size - c), lam))
                                for c in range(0, n.size, _CHUNK)])
            n = np.sort(n[np.argsort(z)[::-1][:24]])
        ds = float(s[-1] - s[0]) / max(s.size - 1, 1)
        blk = max(1, int(0.05 * lam / (n.max() * max(ds, 1e-12) * span)))
        blk = min(blk, max(1, s.size // 64))  # enough blocks to see the phase ramp
        m = (s.size // blk) * blk
        z = y[:m, None] * np.exp(-2j * np.pi * np.outer(s[:m], n / lam))
        blocks.append((z.reshape(-1, blk, n.size).sum(axis=1),
                       s[:m].reshape(-1, blk).mean(axis=1), n / lam, blk * ds))
    if not blocks:
        return lam
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
    return lam / (1.0 + centre)


@dataclass
class _Harmonics:
    """One stroke's harmonics: each one's complex amplitude (v / med)^2 times a piecewise
    linear function over ``knots[n]`` uniform knots from ``lo[n]`` to ``hi[n]`` (0 knots:
    no data); ``ginv`` the inverse normal matrices."""

    lo: Array  # (N,)
    hi: Array  # (N,)
    knots: NDArray[np.int64]  # (N,)
    coef: NDArray[np.complex128]  # (N, K_MAX), the knots' values
    ginv: Array  # (N, K_MAX, K_MAX)
    med: float

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
        """Amplitudes (len(v), count) of harmonics first.. (the edge knots' beyond)."""
        sl = slice(first, None if count is None else first + count)
        i0, w = self._hats(v, sl)
        c = self.coef[sl]
        rows = np.arange(c.shape[0])[None, :]
        out = (1 - w) * c[rows, i0] + w * c[rows, np.minimum(i0 + 1, K_MAX - 1)]
        out *= ((v / self.med) ** 2)[:, None]
        return np.where((self.knots[sl] > 0)[None, :], out, 0.0)

    def noise_gain(self, v: Array) -> Array:
        """b(v)^T G^-1 b(v) (len(v), N): the fit's variance at v per unit of noise (b the
        hat weights at v, G the normal matrix)."""
        i0, w = self._hats(v, slice(None))
        rows = np.arange(self.knots.size)[None, :]
        i1 = np.minimum(i0 + 1, K_MAX - 1)
        g = self.ginv
        return ((1 - w) ** 2 * g[rows, i0, i0] + 2 * w * (1 - w) * g[rows, i0, i1]
                + w ** 2 * g[rows, i1, i1]) * ((v / self.med) ** 4)[:, None]


def _phasors(s: Array, n0: float, count: int, lam: float) -> NDArray[np.complex128]:
    """exp(-j 2 pi n s / lambda) for n = n0, n0 + 1, ..: (len(s), count), by a running
    product (cheaper than exp; exact to ~count x 1e-16)."""
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


def _grid_row(v: Array, grid: Array) -> NDArray[np.int64]:
    return np.clip(np.rint((v - grid[0]) / GRID_STEP_MM_S).astype(int), 0, grid.size - 1)


def _fit_stroke(st: _Stroke, lam: float, n_max: int, f_top: float) -> _Harmonics:
    """Each harmonic n's amplitude c(v) by least squares: the demodulated
    y e^{-j 2 pi n s / lambda} ~ c(v) / 2 (the terms at twice the phase average out over
    many periods), summed per FINE_MM_S speed bin, on the hat basis of 3 to K_MAX knots
    KNOT_HZ of the harmonic's frequency apart over the stroke's speeds (tridiagonal)."""
    idx = np.flatnonzero(st.valid)
    v, y, s = st.v[idx], st.y[idx], st.s[idx]
    bins, vb, cnt = _speed_bins(v)
    total = np.cumsum(cnt)
    summing = sparse.csr_matrix((np.ones(v.size), (bins, np.arange(v.size))),
                                shape=(vb.size, v.size))
    grow = (vb / st.med) ** 2  # an acceleration's lines grow as v^2
    fit = _Harmonics(np.zeros(n_max), np.zeros(n_max), np.zeros(n_max, np.int64),
                     np.zeros((n_max, K_MAX), complex), np.zeros((n_max, K_MAX, K_MAX)), st.med)
    for c0 in range(0, n_max, _CHUNK):
        c_n = min(_CHUNK, n_max - c0)
        n = np.arange(c0, c0 + c_n) + 1.0
        zb = summing @ (_phasors(s, n[0], c_n, lam) * y[:, None])  # (bins, c) sums
        for j in range(c_n):
            nb_in = int(np.searchsorted(vb, f_top * lam / n[j], side="right"))  # in band
            m = int(total[nb_in - 1]) if nb_in else 0
            if m < 64:
                continue
            # The knots span all but the sparse 1 % tails of the speeds (clamped beyond).
            q_lo = int(np.searchsorted(total, m // 100, side="right"))
            q_hi = int(np.searchsorted(total, m - m // 100, side="left"))
            lo, hi = float(vb[min(q_lo, nb_in - 1)]), float(vb[min(q_hi, nb_in - 1)])
            k = (int(np.clip(1 + math.ceil((hi - lo) * n[j] / lam / KNOT_HZ), 3, K_MAX))
                 if hi > lo else 1)
            w_cnt, zj, gj = cnt[:nb_in], zb[:nb_in, j], grow[:nb_in]
            if k > 1:
                x = np.clip((vb[:nb_in] - lo) / (hi - lo) * (k - 1), 0.0, k - 1 - 1e-9)
                i0 = x.astype(np.int64)
                w1 = (x - i0) * gj
                w0 = (1 - (x - i0)) * gj

                diag = (np.bincount(i0, w_cnt * w0 * w0, k)
                        + np.bincount(i0 + 1, w_cnt * w1 * w1, k))
                off = np.bincount(i0, w_cnt * w0 * w1, k)[:-1]
                g = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
                g += np.eye(k) * 1e-6 * diag.sum() / k  # a knot with little data near it
                rhs = [np.bincount(i0, w0 * z, k) + np.bincount(i0 + 1, w1 * z, k)
                       for z in (zj.real, zj.imag)]
                gi = np.linalg.inv(g)
                c = 2.0 * (gi @ (rhs[0] + 1j * rhs[1]))
            else:
                gi = np.array([[1.0 / float(np.dot(w_cnt * gj, gj))]])
                c = np.array([2.0 * complex(np.dot(gj, zj)) * gi[0, 0]])
            h = c0 + j
            fit.ginv[h, :k, :k] = gi
            fit.lo[h], fit.hi[h], fit.knots[h] = lo, hi, k
            fit.coef[h, :k] = c
            fit.coef[h, k:] = c[-1]
    return fit


def _lines(st: _Stroke, fit: _Harmonics, lam: float, f_top: float,
           use_at: Mask | None = None, grid: Array | None = None) -> Array:
    """The stroke's fitted harmonics summed over its valid samples, in band up to
    ``f_top`` and, given ``use_at``, where ``use_at[grid row of the speed, n]``."""
    idx = np.flatnonzero(st.valid)
    vv, ss_ = st.v[idx], st.s[idx]
    n_max = fit.knots.size
    bins, vb, _ = _speed_bins(vv)  # the amplitudes are a function of speed alone
    line = np.zeros(idx.size)
    for c0 in range(0, n_max, _CHUNK):
        cnt = min(_CHUNK, n_max - c0)
        n = np.arange(c0, c0 + cnt) + 1.0
        use = np.outer(vb, n / lam) <= f_top
        if use_at is not None:
            use = use_at[_grid_row(vb, grid), c0:c0 + cnt] & use
        amp = fit.at(vb, c0, cnt) * use
        line += np.sum(np.real(amp[bins] * np.conj(_phasors(ss_, n[0], cnt, lam))), axis=1)
    return line


def _factor_model(power: Array, present: Mask, grid: Array, lam: float, fs_hz: float
                  ) -> Array:
    """log P_n(v) ~ u_n + t(n v / lambda) + g(v) (a surface's harmonic levels through a
    tool's response, piecewise linear every 10 Hz, scaled by the drive per grid row) by
    least squares on the log power of the harmonics present, second differences of t and
    g penalised; exp of it at every (row, harmonic)."""
    nb, n_h = power.shape
    rows, harm = np.nonzero(present & (power > 0))
    if rows.size == 0:
        return np.zeros_like(power)
    f_knots = np.arange(0.0, fs_hz / 2 + 10.0, 10.0)
    nf = f_knots.size
    x = np.clip(grid[rows] * (harm + 1) / lam / 10.0, 0.0, nf - 1 - 1e-9)
    i0 = x.astype(int)
    w1 = x - i0
    m = rows.size
    r = np.arange(m)
    cols = n_h + nf + nb  # u (n_h), t (nf), g (nb)
    a = sparse.csr_matrix((np.concatenate([np.ones(m), 1 - w1, w1, np.ones(m)]),
                           (np.concatenate([r, r, r, r]),
                            np.concatenate([harm, n_h + i0, n_h + i0 + 1, n_h + nf + rows]))),
                          shape=(m, cols))

    def second_diff(k: int, start: int) -> sparse.csr_matrix:
        if k < 3:  # a one- or two-row speed grid (a constant-speed rig): nothing to bend
            return sparse.csr_matrix((0, cols))
        d = sparse.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(k - 2, k))
        return sparse.hstack([sparse.csr_matrix((d.shape[0], start)), d,
                              sparse.csr_matrix((d.shape[0], cols - start - k))])

    pen = sparse.vstack([second_diff(nf, n_h), second_diff(nb, n_h + nf)])
    lhs = (a.T @ a + m / max(pen.shape[0], 1) * (pen.T @ pen)
           + 1e-6 * sparse.identity(cols)).tocsc()
    sol = spla.spsolve(lhs, a.T @ np.log(power[rows, harm]))
    u, t, g = sol[:n_h], sol[n_h:n_h + nf], sol[n_h + nf:].copy()
    # Across rows without lines g is a power law between its ends: the penalty alone
    # bent it (R1 at 15 mm/s, between strokes at 10 and 20: +2 dB on every line).
    have = np.unique(rows)
    gap = np.setdiff1d(np.arange(have[0] + 1, have[-1]), have)
    g[gap] = np.interp(np.log(grid[gap]), np.log(grid[have]), g[have])
    f_all = np.outer(grid, np.arange(1, n_h + 1) / lam)
    return np.exp(u[None, :] + np.interp(f_all, f_knots, t) + g[:, None])


def _fill(power: Array, present: Mask, data: Mask, model: Array) -> Array:
    """One harmonic's power at every grid row: the measured line where there is data (0
    under the noise); elsewhere the factor model times its error at the nearest rows
    with the line, fading linearly to 0 towards a row with data and no line.

    Not carried at all from a single row next to data: a stroke's few fastest or
    slowest instants, where noise over the threshold grew 15 dB across a gap (canvas,
    +3.1 dB LSD at 15 mm/s); a single isolated row (a constant-speed rig) is carried."""
    out = np.where(data, power, 0.0)
    rows = np.flatnonzero(present)  # (a present row always has data)
    if rows.size == 0 or (rows.size == 1 and data[max(rows[0] - 1, 0):rows[0] + 2].sum() > 1):
        return out
    x = np.arange(power.size, dtype=float)
    pred = model * np.exp(np.interp(x, rows, np.log(power[rows] / model[rows])))
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
        elif on_l or on_r:
            w = (i - left) / (right - left)
            out[i] = pred[i] * ((1 - w) if on_l else w)
    return out


def fit_lines(signals: Sequence[Array], speeds: Sequence[Array], fs_hz: float,
              speed_range: tuple[float, float], *, period_mm: float | None = None
              ) -> LineFit:
    """The line spectrum of preprocessed strokes (see the module docstring).

    ``speed_range``: the modelled speeds (mm/s); ``period_mm``: a known period (refined
    within 2 %; the lines are then kept whatever their share). Without a periodic part
    (or one below ``MIN_SHARE`` of the power) the residuals are the signals and every
    sample may be used.
    """
    signals = [np.asarray(y, float) for y in signals]
    speeds = [np.asarray(v, float) for v in speeds]
    f_top = BAND_TOP * fs_hz / 2
    f_lo = 15.0  # above the 10 Hz high-pass's knee
    strokes = [st for i, (y, v) in enumerate(zip(signals, speeds, strict=True))
               if (st := _stroke(i, y, v, speed_range, fs_hz)) is not None]
    if not strokes:
        return LineFit.none(signals, "no stroke holds 0.5 s within the modelled speeds")
    rib = None  # a rib's highest harmonic (None: a comb or a given period)
    if period_mm is not None:
        lam = _refine(strokes, float(period_mm), f_lo, f_top, 0.02)
    elif (lam := _comb_period(strokes, f_lo, f_top)) is None:
        if (found := _rib(strokes, f_top)) is None:
            return LineFit.none(signals, "no spatial period (no harmonic comb stands out of "
                                "the spectrum, nor a rib's line in every stroke whose band "
                                "holds it)")
        lam, rib = found
    n_max = int(max(math.floor(f_top * lam / float(st.v[st.valid].min())) for st in strokes))
    if rib is not None:
        # Only the harmonics that stood as peaks: every one in band gave corduroy 47
        # narrow lines of noise (held out 0.04-0.11 dB worse than its one line).
        n_max = min(n_max, rib)
    capped = n_max > MAX_HARMONICS
    n_max = min(n_max, MAX_HARMONICS)
    if n_max < 1:
        return LineFit.none(signals, f"period {lam:.4g} mm: no harmonic within the band")
    grid = np.arange(math.floor(speed_range[0] / GRID_STEP_MM_S) * GRID_STEP_MM_S,
                     speed_range[1] + GRID_STEP_MM_S / 2, GRID_STEP_MM_S)
    grid = grid[grid > 0]
    nb = grid.size
    p_sum, q_sum, w_sum = np.zeros((nb, n_max)), np.zeros((nb, n_max)), np.zeros((nb, n_max))
    strong = np.zeros((nb, n_max), bool)
    fits = [_fit_stroke(st, lam, n_max, f_top) for st in strokes]
    harm = np.arange(1, n_max + 1) / lam  # cycles/mm
    for st, fit in zip(strokes, fits, strict=True):
        cnt = np.bincount(_grid_row(st.v[st.valid], grid), minlength=nb).astype(float)
        rows = np.flatnonzero(cnt)
        w = cnt[rows, None] * (np.outer(grid[rows], harm) <= f_top) * (fit.knots > 0)[None, :]
        p_rows = np.abs(fit.at(grid[rows])) ** 2
        # What noise alone gives the fit, E|c(v)|^2 = 2 P(f) fs b^T G^-1 b, with P the
        # spectrum of what every harmonic's fit leaves (median-smoothed: no line in it).
        rest = st.y[st.valid] - _lines(st, fit, lam, f_top)
        f, p = ss.welch(rest, fs_hz, nperseg=int(min(256, rest.size)))
        p = ndi.median_filter(p, size=5, mode="nearest")
        q_rows = 2.0 * np.interp(np.outer(grid[rows], harm), f, p) * fs_hz * fit.noise_gain(
            grid[rows])
        p_sum[rows] += w * p_rows
        q_sum[rows] += w * q_rows
        w_sum[rows] += w
        # A stroke's own fit far out makes the line present at a row (a speed few strokes
        # reached); not at the pool's threshold, which would keep many weak cells of noise.
        strong[rows] |= (w > 0) & (p_rows > OWN_SNR_FACTOR * DEFAULT_SNR * q_rows)
    data = w_sum >= MIN_BIN_S * fs_hz
    with np.errstate(invalid="ignore", divide="ignore"):
        p_mean = np.where(data, p_sum / w_sum, 0.0)
        q_mean = np.where(data, q_sum / w_sum, 0.0)
    present = data & ((p_mean > DEFAULT_SNR * q_mean) | strong)
    # A line persists from one row to the next, noise over the threshold does not: a row
    # counts unless every neighbour with data disagrees.
    agree = np.zeros_like(present)
    agree[1:] |= present[:-1] | ~data[:-1]
    agree[:-1] |= present[1:] | ~data[1:]
    agree[[0, -1]] |= nb == 1
    present &= agree
    # Amplitude^2 of the line alone; at least a quarter of the mean where one stroke's
    # fit made it present.
    power = np.where(present, np.maximum(p_mean - q_mean, 0.25 * p_mean), 0.0)
    present &= power > 0
    if not present.any():
        return LineFit.none(signals, f"period {lam:.4g} mm: no harmonic stands over the noise",
                            lam)
    model = _factor_model(power, present, grid, lam, fs_hz)
    table = np.zeros_like(power)
    for n in range(n_max):
        table[:, n] = _fill(power[:, n], present[:, n], data[:, n], model[:, n])
    # A row is mixed in up to the next row's speed: its harmonics must stay in band there.
    freq = np.outer(grid + GRID_STEP_MM_S, harm)
    taper = np.clip((BAND_TOP * fs_hz / 2 - freq) / ((BAND_TOP - TAPER_START) * fs_hz / 2),
                    0.0, 1.0)
    amplitude = np.sqrt(table) * (0.5 - 0.5 * np.cos(np.pi * taper))
    # Subtracted where the nearest row with data keeps the harmonic, up to the taper: above
    # it a stroke's fit over-states its harmonics (the decimation filter's roll-off moves
    # faster than its knots; R1 at 40 mm/s: residual up to 6 dB over the signal).
    keep_near = present.copy()
    for n in range(n_max):
        j = np.flatnonzero(data[:, n])
        if j.size:
            keep_near[:, n] = present[j[np.argmin(np.abs(np.arange(nb)[:, None] - j[None, :]),
                                                  axis=1)], n]
    residuals = list(signals)  # a stroke without a line fit: none of it is clean
    keeps = [np.zeros(y.size, bool) for y in signals]
    line_energy = total_energy = 0.0
    for st, fit in zip(strokes, fits, strict=True):
        idx = np.flatnonzero(st.valid)
        r = st.y.copy()
        r[idx] -= _lines(st, fit, lam, TAPER_START * fs_hz / 2, keep_near, grid)
        residuals[st.index] = r
        keeps[st.index] = st.valid.copy()
        line_energy += float(np.dot(st.y[idx], st.y[idx]) - np.dot(r[idx], r[idx]))
        total_energy += float(np.dot(st.y[idx], st.y[idx]))
    share = line_energy / total_energy if total_energy > 0 else 0.0
    if period_mm is None and share < MIN_SHARE:
        return LineFit.none(signals, f"period {lam:.4g} mm: its lines hold {100 * share:.1f} % "
                            f"of the power (< {100 * MIN_SHARE:g} %): left to the all-pole "
                            "model", lam, share)
    ref = min(range(len(strokes)), key=lambda i: (strokes[i].med, -strokes[i].valid.sum()))
    phase = np.angle(fits[ref].at(np.array([strokes[ref].med]))[0])
    kept = int(np.sum(present.any(axis=0)))
    what = f"{kept} harmonics kept" if rib is None else (
        f"a rib: {'one line' if kept == 1 else f'{kept} harmonics'}, no comb")
    note = (f"period {lam:.4f} mm, {what}, {100 * share:.1f} % of the power in "
            + ("the line" if kept == 1 else "lines"))
    if capped:
        note += (f"; harmonics above the {MAX_HARMONICS}th (in band only at the slowest "
                 "speeds) are left to the all-pole model")
    if period_mm is not None and share < MIN_SHARE:
        note += (f"; only {100 * share:.1f} % of the power at the given period: check it "
                 "(it is refined within about 2 %)")
    return LineFit(LineSpectrum(lam, grid, amplitude, phase), residuals, keeps, lam, share,
                   note)
