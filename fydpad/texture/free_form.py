"""Speed-resolved spectra S(f, v) beyond the two-part model (docs/texture.md,
"Speed-resolved spectra: calibrated two-part and free-form").

Three forms, each fitted on the same 0.5 s Hann chunks as :mod:`two_part` and rendered
as the two-part model is (the renderer's 0.25 mm/s table of two-stage all-pole fits of
S averaged over v +- 1 mm/s; the 1 kHz path unchanged):

- ``"calibrated"`` (the one that helps): S = S_two(f, v) * C(f, v). At each fitted speed
  v_i, C_i = (the mean periodogram of the runs segmented near v_i, the data the pooled
  fit uses) / (S_two averaged over those runs' own sample speeds, with the render's +-1
  mm/s average). A held-out stroke whose speeds wander as the training strokes' did then
  gets the pooled spectrum on average (what the pooled fit gets right: combs, whose
  lines the factorisation misplaces), while S_two still follows the finger's speed
  within the stroke (what the pooled fit gets wrong: spectra that jump with speed).
  log C is weighted by a tent of half-width ``taper_mm_s`` around each v_i (7.5 mm/s,
  chosen on seed set C; at most 0.75 x the distance to the next v_i), so between the
  speeds S leans back towards S_two. S_two is fitted by the two-part model's own 600
  iterations (150 with a single fitted speed: ``ONE_SPEED_BASE_ITERATIONS``).
- ``"free"``: S free in f, piecewise linear in v between knots every 2.5 mm/s; chunk c
  predicted as sum_k m_ck S_k(f) (m_ck: its samples' hat weights on the knots, weighted
  by the window's energy), fitted bin by bin by Itakura-Saito multiplicative updates
  (the maximum-likelihood fit of periodograms; Fevotte et al. 2009). No factorisation,
  but a line moving with speed is cross-faded between knots and each knot has few chunks.
- ``"surface"``: the two-part model with its surface part U(k) g(v) freed into Q(k, v),
  piecewise linear in v at fixed spatial frequency k (lines glide between knots, their
  levels free); T, N, n kept; IS updates with a pseudo-observation of U g.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from fydpad.texture.model_file import TextureModel
from fydpad.texture.speed_warp import NFFT
from fydpad.texture.two_part import (
    CHUNK,
    RENDER_SMEAR_MM_S,
    TooLittleData,
    TwoPartSpectrum,
    _hats,
    _resample_matrix,
    _resampled,
    ar_two_stage,
    chunk_periodograms,
)

Array = NDArray[np.float64]
FORMS = ("calibrated", "free", "surface")
#: fit_texture's form when none is named (docs/texture.md: it meets the targets on more
#: textures, at and between the fitted speeds, than the pooled fit), and the name of that
#: choice (resolved to None with the two-part or speed-normalised options).
DEFAULT_FORM = "calibrated"
AUTO = "auto"
TAPER_MM_S = 7.5  # chosen on seed set C (docs/texture.md); 5 and log-linear also tried
#: ... and at most this times the distance to the next fitted speed: fitted every 5 mm/s,
#: 7.5 mm/s tents summed three corrections at every speed (15 mm/s met 6 of 14 on two
#: seed sets, against 11 and 10 scaled).
TAPER_PER_SPACING = 0.75
#: IS-NMF iterations of the calibrated form's two-part base with a single fitted speed.
#: With two or more the base takes the two-part model's own 600 (two_part.ITERATIONS):
#: C_i makes S at each fitted speed the recorded one whatever the base, so the base
#: decides what lies between the speeds, and there 600 iterations met more cells than 150
#: on the scan generator (means of 8 strokes: 93 / 94 / 93 of 98 against 90 / 93 / 93 on
#: three seed sets).
#: With one speed nothing lies between, and 150 keep that fit at 33 ms (600: 94 ms, at
#: the 100 ms target for a fit of one speed).
ONE_SPEED_BASE_ITERATIONS = 150
STEP = 0.5  # MU exponent: the IS divergence's majorisation (monotone)
_EPS = 1e-300


def _ar(spec, speed_mm_s: float, order: int, fs_hz: float) -> tuple[Array, float]:
    """All-pole (A, sigma^2) of ``spec.psd`` averaged over v +- RENDER_SMEAR_MM_S: the
    two-part renderer's entry (:meth:`two_part.TwoPartSpectrum.ar`)."""
    vs = speed_mm_s + RENDER_SMEAR_MM_S * np.linspace(-1.0, 1.0, 5)
    p = np.mean([spec.psd(float(v)) for v in vs], axis=0)
    f = np.arange(NFFT // 2 + 1) * fs_hz / NFFT
    log_p = np.interp(f, spec.f_hz, np.log(np.maximum(p, _EPS)))
    return ar_two_stage(log_p, order)


def _rows(a: Array) -> list[list[float]]:
    return [[float(x) for x in row] for row in a]


@dataclass
class CalibratedSpectrum:
    """S(f, v) = S_two(f, v) exp(sum_i w_i(v) log C_i(f)) (module docstring)."""

    two: TwoPartSpectrum
    v_mm_s: Array  # the fitted speeds v_i
    log_c: Array  # (speeds, f)
    taper_mm_s: float | None = TAPER_MM_S  # None: log-linear between speeds, held beyond

    @property
    def f_hz(self) -> Array:
        return self.two.f_hz

    def weights(self, speed_mm_s: float) -> Array:
        """w_i(v): a tent of half-width :attr:`half_widths_mm_s` around each v_i (speeds
        clamped to the fitted range), or the hat weights of linear interpolation."""
        v = float(np.clip(speed_mm_s, self.v_mm_s[0], self.v_mm_s[-1]))
        if self.taper_mm_s is None:
            return _hats(np.array([v]), self.v_mm_s)[0]
        return np.maximum(0.0, 1.0 - np.abs(v - self.v_mm_s) / self.half_widths_mm_s)

    @property
    def half_widths_mm_s(self) -> Array:
        """Each correction's tent: ``taper_mm_s``, at most TAPER_PER_SPACING x the
        distance to the next fitted speed (7.5 mm/s at the paper's 10 mm/s steps)."""
        if self.v_mm_s.size < 2:
            return np.full(self.v_mm_s.size, float(self.taper_mm_s))
        gap = np.diff(self.v_mm_s)
        near = np.minimum(np.r_[np.inf, gap], np.r_[gap, np.inf])
        return np.minimum(float(self.taper_mm_s), TAPER_PER_SPACING * near)

    def psd(self, speed_mm_s: float) -> Array:
        return self.two.psd(speed_mm_s) * np.exp(self.weights(speed_mm_s) @ self.log_c)

    def ar(self, speed_mm_s: float, order: int, fs_hz: float) -> tuple[Array, float]:
        return _ar(self, speed_mm_s, order, fs_hz)

    def to_json(self) -> dict:
        return {"form": "calibrated", "f_hz": [float(x) for x in self.f_hz],
                "v_mm_s": [float(x) for x in self.v_mm_s], "log_c": _rows(self.log_c),
                "taper_mm_s": self.taper_mm_s}


@dataclass
class FreeFormSpectrum:
    """S on ``f_hz`` x knots ``v_mm_s``, linear in v between knots, held beyond."""

    f_hz: Array
    v_mm_s: Array
    s: Array  # (knots, f)

    def psd(self, speed_mm_s: float) -> Array:
        v = float(np.clip(speed_mm_s, self.v_mm_s[0], self.v_mm_s[-1]))
        return _hats(np.array([v]), self.v_mm_s)[0] @ self.s

    def ar(self, speed_mm_s: float, order: int, fs_hz: float) -> tuple[Array, float]:
        return _ar(self, speed_mm_s, order, fs_hz)

    def to_json(self) -> dict:
        return {"form": "free", "f_hz": [float(x) for x in self.f_hz],
                "v_mm_s": [float(x) for x in self.v_mm_s], "psd": _rows(self.s)}


@dataclass
class SurfaceResolvedSpectrum:
    """S(f, v) = T(f) Q(f / v, v) + N(f) n(v), Q linear in v between knots at fixed k."""

    two: TwoPartSpectrum  # T, N, n and the k grid
    v_mm_s: Array  # knots of Q
    q: Array  # (knots, k)

    @property
    def f_hz(self) -> Array:
        return self.two.f_hz

    def psd(self, speed_mm_s: float) -> Array:
        tp = self.two
        v = float(np.clip(speed_mm_s, tp.v_mm_s[0], tp.v_mm_s[-1]))
        n = np.exp(np.interp(v, tp.v_mm_s, np.log(tp.n)))
        qv = _hats(np.array([v]), self.v_mm_s)[0] @ self.q
        return tp.tool * _resampled(qv, tp.k_per_mm, tp.f_hz, v) + tp.floor * n

    def ar(self, speed_mm_s: float, order: int, fs_hz: float) -> tuple[Array, float]:
        return _ar(self, speed_mm_s, order, fs_hz)

    def to_json(self) -> dict:
        return {"form": "surface", "v_mm_s": [float(x) for x in self.v_mm_s],
                "q": _rows(self.q)}


Spectrum = CalibratedSpectrum | FreeFormSpectrum | SurfaceResolvedSpectrum


def fit_calibrated(runs_by_speed: dict[float, list[tuple[Array, Array]]], fs_hz: float,
                   two: TwoPartSpectrum, *, taper_mm_s: float | None = TAPER_MM_S,
                   chunk: int = CHUNK, grid_mm_s: float = 0.25) -> CalibratedSpectrum:
    """C_i for each fitted speed v_i from its segmented runs ``runs_by_speed[v_i] =
    [(x, speed trace), ...]`` (module docstring); runs shorter than a chunk are skipped."""
    speeds, rows = [], []
    smear = RENDER_SMEAR_MM_S * np.linspace(-1.0, 1.0, 5)
    for s, rv in sorted(runs_by_speed.items()):
        rv = [(x, v) for x, v in rv if x.size >= chunk]
        if not rv:
            continue
        p, _ = chunk_periodograms([x for x, _ in rv], [v for _, v in rv], fs_hz, chunk)
        # S_two averaged over the runs' sample speeds: a histogram on a fine grid.
        allv = np.concatenate([v for _, v in rv])
        edges = np.arange(allv.min(), allv.max() + 2 * grid_mm_s, grid_mm_s)
        hist, _ = np.histogram(allv, edges)
        mid = 0.5 * (edges[:-1] + edges[1:])[hist > 0]
        e = two.mean_psd((mid[:, None] + smear).ravel(), np.repeat(hist[hist > 0], smear.size))
        rows.append(np.log(np.maximum(p[:, 1:].mean(axis=0), _EPS) / np.maximum(e, _EPS)))
        speeds.append(s)
    if not speeds:
        raise TooLittleData("no speed has a run as long as one 0.5 s chunk")
    return CalibratedSpectrum(two, np.asarray(speeds), np.vstack(rows), taper_mm_s)


def _chunks_in(runs: Sequence[Array], speeds: Sequence[Array], fs_hz: float,
               speed_range_mm_s: tuple[float, float], chunk: int
               ) -> tuple[Array, list[Array], Array]:
    """The chunks within the speed range: periodograms without DC, their sample speeds,
    the bin frequencies."""
    lo, hi = speed_range_mm_s
    p_all, v_all = chunk_periodograms(runs, speeds, fs_hz, chunk)
    keep = [i for i, v in enumerate(v_all) if v.min() >= lo and v.max() <= hi]
    if not keep:
        raise TooLittleData("no 0.5 s chunk of the scans stays within the modelled speeds")
    return p_all[keep][:, 1:], [v_all[i] for i in keep], np.fft.rfftfreq(chunk, 1 / fs_hz)[1:]


def fit_free_form(runs: Sequence[Array], speeds: Sequence[Array], fs_hz: float,
                  speed_range_mm_s: tuple[float, float], *, knot_step_mm_s: float = 2.5,
                  iterations: int = 100, chunk: int = CHUNK,
                  wrap: Callable[[Iterable], Iterable] = lambda it: it) -> FreeFormSpectrum:
    """The ``"free"`` form (module docstring) on preprocessed ``runs`` with speed traces
    ``speeds``. Starts from each knot's weighted chunk mean (knots without data take
    their neighbours'); the IS updates converge within ~50 iterations here."""
    p, vs, f = _chunks_in(runs, speeds, fs_hz, speed_range_mm_s, chunk)
    lo, hi = speed_range_mm_s
    knots = np.arange(np.floor(lo), np.ceil(hi) + knot_step_mm_s / 2, knot_step_mm_s)
    w = np.hanning(chunk) ** 2
    w /= w.sum()  # a periodogram's expectation: the window-energy-weighted local spectra
    m = np.stack([w @ _hats(v, knots) for v in vs])  # (C, K)
    rho = m.sum(axis=0)
    # A knot with less than one chunk's worth of data is not fitted (its value would
    # follow the residuals of the chunks it barely touches: measured +76 dB on R2 with
    # one stroke per speed); it takes its neighbours' values, log-linear in v.
    have = rho >= 1.0
    if not have.any():
        raise ValueError("no speed knot has a whole 0.5 s chunk of data")
    s = (m.T @ p) / np.maximum(rho, _EPS)[:, None]

    def fill(s: Array) -> Array:
        out = np.empty_like(s)
        for j in range(f.size):
            out[:, j] = np.exp(np.interp(knots, knots[have], np.log(s[have, j])))
        return out

    s = fill(np.maximum(s, _EPS))
    for _ in wrap(range(iterations)):
        pred = np.maximum(m @ s, _EPS)
        top, bottom = m.T @ (p / pred**2), m.T @ (1.0 / pred)
        s[have] *= (top[have] / np.maximum(bottom[have], _EPS)) ** STEP
        np.maximum(s, 1e-30 * s.max(), out=s)
    return FreeFormSpectrum(f, knots, fill(s))


def fit_surface_resolved(runs: Sequence[Array], speeds: Sequence[Array], fs_hz: float,
                         speed_range_mm_s: tuple[float, float], two: TwoPartSpectrum, *,
                         knot_step_mm_s: float = 5.0, prior_weight: float = 1.0,
                         iterations: int = 100, chunk: int = CHUNK,
                         wrap: Callable[[Iterable], Iterable] = lambda it: it
                         ) -> SurfaceResolvedSpectrum:
    """The ``"surface"`` form: Q(k, v_knot) starts at U(k) g(v_knot) of the fitted ``two``
    and is refined by IS updates on the chunks, with a pseudo-observation of U g of
    weight ``prior_weight`` at every knot; T, N and n stay."""
    p, vs, f = _chunks_in(runs, speeds, fs_hz, speed_range_mm_s, chunk)
    k, vgrid = two.k_per_mm, two.v_mm_s
    w = np.vstack([_hats(v, vgrid).mean(axis=0) for v in vs])  # (C, nv)
    knots = np.arange(vgrid[0], vgrid[-1] + knot_step_mm_s / 2, knot_step_mm_s)
    phi = _hats(vgrid, knots)  # (nv, K)
    bbig = sp.vstack([_resample_matrix(f, v, k) for v in vgrid]).tocsr()
    bbig_t = bbig.T.tocsr()
    nv, nf = vgrid.size, f.size
    g_knots = np.exp(np.interp(knots, vgrid, np.log(two.g)))
    prior = g_knots[:, None] * two.surface[None, :]
    prior = np.maximum(prior, 1e-30 * prior.max())  # U may hold exact zeros
    q = prior.copy()
    floor_part = two.floor[None, :] * two.n[:, None]
    for _ in wrap(range(iterations)):
        x = np.einsum("vfk,vk->vf", (bbig @ q.T).reshape(nv, nf, knots.size), phi)
        s = np.maximum(w @ (two.tool * x + floor_part), _EPS)
        gn, gp = w.T @ (p / s**2), w.T @ (1.0 / s)
        top = (bbig_t @ ((gn * two.tool)[:, :, None] * phi[:, None, :]).reshape(nv * nf, -1)).T
        bottom = (bbig_t @ ((gp * two.tool)[:, :, None] * phi[:, None, :]).reshape(nv * nf, -1)).T
        top += prior_weight * prior / q**2
        bottom += prior_weight / q
        q *= np.where(bottom > 0, top / np.maximum(bottom, _EPS), 1.0) ** STEP
        np.maximum(q, 1e-30 * q.max(), out=q)
    return SurfaceResolvedSpectrum(two, knots, q)


def spectrum_of(model: TextureModel) -> Spectrum:
    """The model's ``free_form`` block as a spectrum (``form`` says which)."""
    d = model.free_form
    form = d.get("form")
    if form == "free":
        return FreeFormSpectrum(np.asarray(d["f_hz"], float), np.asarray(d["v_mm_s"], float),
                                np.asarray(d["psd"], float))
    two = TwoPartSpectrum.from_json(model.two_part)
    if form == "calibrated":
        taper = d.get("taper_mm_s")
        return CalibratedSpectrum(two, np.asarray(d["v_mm_s"], float),
                                  np.asarray(d["log_c"], float),
                                  None if taper is None else float(taper))
    return SurfaceResolvedSpectrum(two, np.asarray(d["v_mm_s"], float),
                                   np.asarray(d["q"], float))
