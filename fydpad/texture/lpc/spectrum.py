"""The calibrated form's speed-resolved spectrum (docs/texture.md, "The calibrated
spectrum"): a two-part base

    S_two(f, v) = T(f) U(f / v) g(v) + N(f) n(v) + N0(f)

(T the tool, U the surface in spatial frequency, N n a fixed additive part, N0 the sensor's
floor; g, n linear in log v between knots), fitted jointly on every 0.5 s chunk at its
samples' speeds by IS-NMF multiplicative updates (Fevotte et al. 2009), times a correction
C_i measured at each fitted speed v_i, log C_i weighted by a tent around v_i.
"""

from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from threadpoolctl import ThreadpoolController

from fydpad.texture.lpc.analysis import NFFT, ar_from_log_psd
from fydpad.texture.lpc.model_file import TextureModel

Array = NDArray[np.float64]
CHUNK = 512  # samples per periodogram (2 Hz bins at 1 kHz)
SPEED_STEP_MM_S = 1.0  # grid of the level functions g, n and of the chunks' speed mixes
KNOT_STEP_MM_S = 5.0
ITERATIONS = 600
#: S is rendered averaged over v +- this (the FIR mixes table entries 0.25 mm/s apart).
RENDER_SMEAR_MM_S = 1.0
_SMEAR_MM_S = RENDER_SMEAR_MM_S * np.linspace(-1.0, 1.0, 5)  # the offsets S is averaged at
PREWHITEN_ORDER = 8  # of the two-stage all-pole fit (ar_two_stage)
_SUB = 8  # points across each f bin where U(f / v) is averaged
STEP = 0.5  # MU exponent: 1/2 is the IS divergence's majorisation (monotone)
KNOT_MIN_CHUNKS = 8.0  # chunks a level knot needs within half a knot step (~2 s of a stroke)
U_MIN_CHUNKS = 1.0  # chunk weight a spatial frequency needs; those seen less hold the nearest
MAX_EXTRAPOLATION_POWER = 4.0  # bound on a level's log-log slope beyond the end knots
TAPER_MM_S = 7.5  # half-width of each correction's tent ...
TAPER_PER_SPACING = 0.75  # ... at most this times the distance to the next fitted speed


@dataclass
class TwoPartSpectrum:
    """The fitted factors (module equation); ``f_hz`` and ``k_per_mm`` are their grids."""

    f_hz: Array
    k_per_mm: Array
    tool: Array  # T(f)
    surface: Array  # U(k)
    floor: Array  # N(f)
    v_mm_s: Array  # speed grid of the levels
    g: Array  # g(v)
    n: Array  # n(v)
    fixed_floor: Array  # N0(f)

    def _levels(self, v: float | Array) -> tuple[Array, Array, Array]:
        """The speeds clipped to the level grid, and g and n there (linear in log v)."""
        v = np.clip(v, self.v_mm_s[0], self.v_mm_s[-1])
        g = np.exp(np.interp(v, self.v_mm_s, np.log(self.g)))
        return v, g, np.exp(np.interp(v, self.v_mm_s, np.log(self.n)))

    def psd(self, speed_mm_s: float) -> Array:
        """S_two(f, v) on ``f_hz`` (power per bin: mean = power), levels held beyond."""
        v, g, n = self._levels(float(speed_mm_s))
        u = _resampled(self.surface, self.k_per_mm, self.f_hz, v)
        return self.tool * u * g + self.floor * n + self.fixed_floor

    def mean_psd(self, speeds_mm_s: ArrayLike, weights: ArrayLike | None = None) -> Array:
        """The ``weights``-weighted mean of :meth:`psd` over ``speeds_mm_s``, in one pass."""
        v, g, n = self._levels(np.ravel(np.asarray(speeds_mm_s, float)))
        w = np.ones(v.size) if weights is None else np.asarray(weights, float)
        w = w / w.sum()
        u = _resampled(self.surface, self.k_per_mm, self.f_hz, v)
        return self.tool * ((w * g) @ u) + self.floor * float(w @ n) + self.fixed_floor

    def to_json(self) -> dict:
        return {f.name: [float(x) for x in getattr(self, f.name)] for f in fields(self)}

    @classmethod
    def from_json(cls, d: dict) -> TwoPartSpectrum:
        return cls(**{f.name: np.asarray(d[f.name], float) for f in fields(cls)})


def ar_two_stage(log_p: Array, order: int) -> tuple[Array, float]:
    """All-pole fit A = A2 P to a log spectrum: an order-``PREWHITEN_ORDER`` P flattens
    the tilt, A2 fits the rest (one stage over-fills the valleys of a 50-60 dB spectrum)."""
    q = min(PREWHITEN_ORDER, order - 1)
    if q == 0:
        return ar_from_log_psd(log_p, order)
    pre, _ = ar_from_log_psd(log_p, q)
    flat = log_p + np.log(np.abs(np.fft.rfft(pre, 2 * (log_p.size - 1))) ** 2)
    a2, s2 = ar_from_log_psd(flat, order - q)
    return np.convolve(a2, pre), s2


def chunk_periodograms(runs: Sequence[Array], speeds: Sequence[Array]) -> tuple[Array, list[Array]]:
    """Hann periodograms (mean = power) of 50 %-overlapping chunks, and each chunk's
    sample speeds."""
    w = np.hanning(CHUNK)
    norm = np.dot(w, w)
    ps, vs = [], []
    for x, v in zip(runs, speeds, strict=True):
        for a in range(0, x.size - CHUNK + 1, CHUNK // 2):
            ps.append(np.abs(np.fft.rfft(x[a:a + CHUNK] * w)) ** 2 / norm)
            vs.append(np.asarray(v[a:a + CHUNK], float))
    return (np.vstack(ps) if ps else np.zeros((0, CHUNK // 2 + 1))), vs


class TooLittleData(ValueError):
    """No 0.5 s chunk within the modelled speeds: no spectral model (the per-speed fit can)."""


def _bin_k(f_hz: Array, v: float | Array) -> Array:
    """k = f / v at ``_SUB`` points across each f bin (f, _SUB), a block per speed if ``v`` is
    an array: U is averaged over each bin's width, so every node a slow speed's 2 Hz bin
    covers is constrained (point sampling left some at their start value and S flickered
    from one speed to the next)."""
    off = (np.arange(_SUB) + 0.5) / _SUB - 0.5
    return (f_hz[:, None] + (f_hz[1] - f_hz[0]) * off) / np.asarray(v, float)[..., None, None]


def _resample_matrix(f_hz: Array, v: float, k: Array) -> sp.csr_matrix:
    """U(f / v) on the f bins as a matrix (f bins x k nodes), for the fit."""
    x = _bin_k(f_hz, v).ravel()
    j = np.clip(np.searchsorted(k, x) - 1, 0, k.size - 2)
    t = np.clip((x - k[j]) / (k[j + 1] - k[j]), 0.0, 1.0)
    rows = np.repeat(np.arange(f_hz.size), 2 * _SUB)
    cols = np.stack([j, j + 1], axis=1).ravel()
    vals = np.stack([1 - t, t], axis=1).ravel() / _SUB
    return sp.csr_matrix((vals, (rows, cols)), shape=(f_hz.size, k.size))


def _resampled(u: Array, k: Array, f_hz: Array, v: float | Array) -> Array:
    """U(f / v) on the f bins without the matrix (the render's table asks at hundreds of
    speeds); a row per speed if ``v`` is an array."""
    return np.interp(_bin_k(f_hz, v), k, u).mean(axis=-1)


@functools.cache
def _threadpools() -> ThreadpoolController:
    return ThreadpoolController()  # finding the loaded libraries takes milliseconds


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """BLAS held to one thread for the block (the fit's products are small: threaded BLAS
    on a loaded machine spends 10x their cost in hand-offs); the main thread's only, as the
    limit is the process's."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    with _threadpools().limit(limits=1, user_api="blas"):
        yield


def _hats(x: Array, nodes: Array, clamp: bool = True) -> Array:
    """Linear-interpolation weights (len(x), len(nodes)) of ``x`` on ``nodes``: held at the
    end nodes, or with ``clamp=False`` continued along the end segments."""
    out = np.zeros((np.size(x), nodes.size))
    j = np.clip(np.searchsorted(nodes, x) - 1, 0, nodes.size - 2)
    t = (x - nodes[j]) / (nodes[j + 1] - nodes[j])
    if clamp:
        t = np.clip(t, 0.0, 1.0)
    r = np.arange(np.size(x))
    np.add.at(out, (r, j), 1 - t)
    np.add.at(out, (r, j + 1), t)
    return out


def _node_levels(log_levels: Array, log_v: Array, log_knots: Array, phi: Array) -> Array:
    """Log levels at the speed nodes from the knots' (a column per level if 2-D): linear in
    log v (``phi``), beyond the end knots with slopes bounded by MAX_EXTRAPOLATION_POWER."""
    out = phi @ log_levels
    if log_knots.size < 2:
        return out
    lim = MAX_EXTRAPOLATION_POWER
    for end, nxt, side in ((0, 1, log_v < log_knots[0]), (-1, -2, log_v > log_knots[-1])):
        if side.any():
            slope = (log_levels[nxt] - log_levels[end]) / (log_knots[nxt] - log_knots[end])
            dv = (log_v[side] - log_knots[end]).reshape(-1, *(1,) * (log_levels.ndim - 1))
            out[side] = log_levels[end] + np.clip(slope, -lim, lim) * dv
    return out


def fit_two_part(runs: Sequence[Array], speeds: Sequence[Array], fs_hz: float,
                 speed_range_mm_s: tuple[float, float], iterations: int = ITERATIONS,
                 wrap: Callable[[Iterable], Iterable] = lambda it: it) -> TwoPartSpectrum:
    """S_two fitted to preprocessed ``runs`` with speed traces ``speeds``, on the chunks
    within ``speed_range_mm_s``; ``wrap`` wraps the iterations (a progress bar)."""
    lo, hi = speed_range_mm_s
    p_all, v_all = chunk_periodograms(runs, speeds)
    keep = [i for i, v in enumerate(v_all) if v.min() >= lo and v.max() <= hi]
    if not keep:
        raise TooLittleData("no 0.5 s chunk of the scans stays within the modelled speeds")
    p = p_all[keep][:, 1:]  # no DC
    f = np.fft.rfftfreq(CHUNK, 1.0 / fs_hz)[1:]
    vgrid = np.arange(np.floor(lo), np.ceil(hi) + SPEED_STEP_MM_S / 2, SPEED_STEP_MM_S)
    # Mixing weights: chunk c's share of samples at each speed node.
    w = np.vstack([_hats(v_all[i], vgrid).mean(axis=0) for i in keep])
    rho = w.sum(axis=0)  # data at each speed node
    knots = np.arange(vgrid[0], vgrid[-1] + KNOT_STEP_MM_S, KNOT_STEP_MM_S)
    near = np.array([rho[np.abs(vgrid - kn) <= KNOT_STEP_MM_S / 2].sum() for kn in knots])
    if np.count_nonzero(near >= KNOT_MIN_CHUNKS) >= 2:
        knots = knots[near >= KNOT_MIN_CHUNKS]
    # Levels continue along the end segments beyond the end knots (held flat, a stroke's
    # ramps stood 3-5 dB high); the nodes' update ratios pool onto the nearest knots.
    log_v, log_knots = np.log(np.maximum(vgrid, 0.25)), np.log(np.maximum(knots, 0.25))
    phi = _hats(log_v, log_knots, clamp=False)  # speed node <- knots
    pool = _hats(log_v, log_knots)
    kw = pool.T @ rho
    kw_ok = kw > 1e-2 * kw.max()
    dk = (f[1] - f[0]) / vgrid[-1]  # the finest k spacing the data resolve
    k = np.arange(0.0, f[-1] / vgrid[0] + 2 * dk, dk)
    bbig = sp.vstack([_resample_matrix(f, v, k) for v in vgrid]).tocsr()
    bbig_t = bbig.T.tocsr()
    nv, nf = vgrid.size, f.size
    wt = w.T

    mean_p = p.mean(axis=0)
    tool = np.ones(nf)
    surface = np.ones(k.size)
    floor = np.full(nf, 0.05 * mean_p.min() + 1e-30)
    # N0 starts at half the quietest tenth of the chunks (started as low as N, U took the
    # floor's place and kept it).
    fixed = 0.5 * np.percentile(p, 10, axis=0) + 1e-30
    eps = 1e-300
    # The speed nodes' MU ratios pool onto the knots (weighted geometric mean).
    pool_w = pool * rho[:, None]
    pool_w /= np.maximum(pool_w.sum(0), eps)
    pool_wt = np.ascontiguousarray(pool_w.T)
    # (knots, 2): log g and log n, updated together
    levels = np.stack([np.full(knots.size, np.log(float(np.median(mean_p)))),
                       np.zeros(knots.size)], axis=1)
    nc = p.shape[0]
    grad = np.empty((nc, 2, nf))  # p / s^2 and 1 / s per chunk: the IS gradient's parts
    with one_blas_thread():
        for _ in wrap(range(iterations)):
            gn_levels = np.exp(_node_levels(levels, log_v, log_knots, phi))
            g, n = gn_levels[:, :1], gn_levels[:, 1:]
            tg = tool * g
            x = (bbig @ surface).reshape(nv, nf)
            s = w @ (x * tg + floor * n + fixed)
            np.maximum(s, eps, out=s)
            np.divide(1.0, s, out=grad[:, 1])
            np.multiply(p, grad[:, 1] ** 2, out=grad[:, 0])
            # Per speed node, the gradient's positive and negative parts: (nodes, 2, f).
            gnp = (wt @ grad.reshape(nc, 2 * nf)).reshape(nv, 2, nf)
            num = bbig_t @ (gnp[:, 0] * tg).ravel()
            den = bbig_t @ (gnp[:, 1] * tg).ravel()
            surface *= np.where(den > 0, num / np.maximum(den, eps), 1.0) ** STEP
            x = (bbig @ surface).reshape(nv, nf)
            r = np.einsum("vaf,vf->af", gnp, x * g)
            tool *= (r[0] / np.maximum(r[1], eps)) ** STEP
            r = np.einsum("vaf,v->af", gnp, n[:, 0])
            floor *= (r[0] / np.maximum(r[1], eps)) ** STEP
            r = gnp.sum(0)
            fixed *= (r[0] / np.maximum(r[1], eps)) ** STEP
            rg = np.einsum("vaf,vf->va", gnp, x * tool)
            rn = gnp @ floor
            ratio = np.stack([rg[:, 0] / np.maximum(rg[:, 1], eps),
                              rn[:, 0] / np.maximum(rn[:, 1], eps)], axis=1)
            levels += STEP * (pool_wt @ np.log(np.maximum(ratio, eps)))
            # Scale ambiguities (T*U*g, N*n): T and N at unit peak, U at unit mean.
            c = tool.max()
            tool /= c
            c2 = surface.mean()
            surface /= c2
            levels[:, 0] += np.log(c * c2)
            c = floor.max()
            floor /= c
            levels[:, 1] += np.log(c)
    seen = bbig_t @ np.repeat(rho, nf) >= U_MIN_CHUNKS
    if seen.any():
        surface = np.interp(k, k[seen], surface[seen])
    # Knots without data take their neighbours' log-linear level.
    lg, ln = (np.interp(knots, knots[kw_ok], lv[kw_ok]) for lv in levels.T)
    return TwoPartSpectrum(f, k, tool, surface, floor, vgrid,
                           np.exp(_node_levels(lg, log_v, log_knots, phi)),
                           np.exp(_node_levels(ln, log_v, log_knots, phi)), fixed)


@dataclass
class CalibratedSpectrum:
    """S(f, v) = S_two(f, v) exp(sum_i w_i(v) log C_i(f)) (module docstring)."""

    two: TwoPartSpectrum
    v_mm_s: Array  # the fitted speeds v_i
    log_c: Array  # (speeds, f)
    taper_mm_s: float = TAPER_MM_S

    def weights(self, speed_mm_s: float) -> Array:
        """w_i(v): a tent of half-width :attr:`half_widths_mm_s` around each v_i (speeds
        clamped to the fitted range)."""
        v = float(np.clip(speed_mm_s, self.v_mm_s[0], self.v_mm_s[-1]))
        return np.maximum(0.0, 1.0 - np.abs(v - self.v_mm_s) / self.half_widths_mm_s)

    @property
    def half_widths_mm_s(self) -> Array:
        """``taper_mm_s``, at most TAPER_PER_SPACING x the distance to the next v_i."""
        gap = np.diff(self.v_mm_s)
        near = np.minimum(np.r_[np.inf, gap], np.r_[gap, np.inf])
        return np.minimum(float(self.taper_mm_s), TAPER_PER_SPACING * near)

    def psd(self, speed_mm_s: float) -> Array:
        return self.two.psd(speed_mm_s) * np.exp(self.weights(speed_mm_s) @ self.log_c)

    def ar(self, speed_mm_s: float, order: int, fs_hz: float) -> tuple[Array, float]:
        """All-pole (A, sigma^2) of S averaged over v +- RENDER_SMEAR_MM_S."""
        p = np.mean([self.psd(float(v)) for v in speed_mm_s + _SMEAR_MM_S], axis=0)
        f = np.arange(NFFT // 2 + 1) * fs_hz / NFFT
        return ar_two_stage(np.interp(f, self.two.f_hz, np.log(np.maximum(p, 1e-300))), order)

    def to_json(self) -> dict:
        return {"form": "calibrated", "f_hz": [float(x) for x in self.two.f_hz],
                "v_mm_s": [float(x) for x in self.v_mm_s],
                "log_c": [[float(x) for x in row] for row in self.log_c],
                "taper_mm_s": self.taper_mm_s}


def fit_calibrated(runs_by_speed: dict[float, list[tuple[Array, Array]]], two: TwoPartSpectrum
                   ) -> CalibratedSpectrum:
    """C_i for each fitted speed v_i from its segmented runs ``runs_by_speed[v_i] =
    [(x, speed trace), ...]``; runs shorter than a chunk are skipped."""
    speeds, rows = [], []
    for s, rv in sorted(runs_by_speed.items()):
        rv = [(x, v) for x, v in rv if x.size >= CHUNK]
        if not rv:
            continue
        p, _ = chunk_periodograms([x for x, _ in rv], [v for _, v in rv])
        # S_two averaged over the runs' sample speeds: a histogram on a 0.25 mm/s grid.
        allv = np.concatenate([v for _, v in rv])
        edges = np.arange(allv.min(), allv.max() + 2 * 0.25, 0.25)
        hist, _ = np.histogram(allv, edges)
        mid = 0.5 * (edges[:-1] + edges[1:])[hist > 0]
        e = two.mean_psd((mid[:, None] + _SMEAR_MM_S).ravel(),
                         np.repeat(hist[hist > 0], _SMEAR_MM_S.size))
        rows.append(np.log(np.maximum(p[:, 1:].mean(axis=0), 1e-300) / np.maximum(e, 1e-300)))
        speeds.append(s)
    if not speeds:
        raise TooLittleData("no speed has a run as long as one 0.5 s chunk")
    return CalibratedSpectrum(two, np.asarray(speeds), np.vstack(rows))


def spectrum_of(model: TextureModel) -> CalibratedSpectrum:
    """The model's ``free_form`` block (checked by model_file) as a spectrum."""
    d = model.free_form
    return CalibratedSpectrum(TwoPartSpectrum.from_json(model.two_part),
                              np.asarray(d["v_mm_s"], float), np.asarray(d["log_c"], float),
                              float(d["taper_mm_s"]))
