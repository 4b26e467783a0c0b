"""The calibrated spectrum S(f, v) (docs/texture.md, "Speed-resolved spectra").

S = S_two(f, v) * C(f, v), with S_two the two-part model (:mod:`two_part`). At each
fitted speed v_i, C_i = (the mean periodogram of the runs segmented near v_i, the data
the pooled per-speed fit uses) / (S_two averaged over those runs' own sample speeds,
with the render's +-1 mm/s average). A held-out stroke whose speeds wander as the
training strokes' did then gets the pooled spectrum on average (combs, whose lines the
factorisation misplaces), while S_two still follows the finger's speed within the
stroke. log C is weighted by a tent of half-width ``TAPER_MM_S`` around each v_i (at
most ``TAPER_PER_SPACING`` x the distance to the next v_i), so between the speeds S
leans back towards S_two. Rendered as the two-part model is: the renderer's 0.25 mm/s
table of two-stage all-pole fits of S averaged over v +- 1 mm/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.texture.model_file import TextureModel
from fydpad.texture.speed_warp import NFFT
from fydpad.texture.two_part import (
    CHUNK,
    RENDER_SMEAR_MM_S,
    TooLittleData,
    TwoPartSpectrum,
    ar_two_stage,
    chunk_periodograms,
)

Array = NDArray[np.float64]
TAPER_MM_S = 7.5  # chosen on the scan generator's seed set C (docs/texture.md)
#: ... and at most this times the distance to the next fitted speed (7.5 mm/s tents at
#: 5 mm/s steps summed three corrections at every speed).
TAPER_PER_SPACING = 0.75
_EPS = 1e-300


@dataclass
class CalibratedSpectrum:
    """S(f, v) = S_two(f, v) exp(sum_i w_i(v) log C_i(f)) (module docstring)."""

    two: TwoPartSpectrum
    v_mm_s: Array  # the fitted speeds v_i
    log_c: Array  # (speeds, f)
    taper_mm_s: float = TAPER_MM_S

    @property
    def f_hz(self) -> Array:
        return self.two.f_hz

    def weights(self, speed_mm_s: float) -> Array:
        """w_i(v): a tent of half-width :attr:`half_widths_mm_s` around each v_i (speeds
        clamped to the fitted range)."""
        v = float(np.clip(speed_mm_s, self.v_mm_s[0], self.v_mm_s[-1]))
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
        """All-pole (A, sigma^2) of S averaged over v +- RENDER_SMEAR_MM_S, as
        :meth:`two_part.TwoPartSpectrum.ar`."""
        vs = speed_mm_s + RENDER_SMEAR_MM_S * np.linspace(-1.0, 1.0, 5)
        p = np.mean([self.psd(float(v)) for v in vs], axis=0)
        f = np.arange(NFFT // 2 + 1) * fs_hz / NFFT
        return ar_two_stage(np.interp(f, self.f_hz, np.log(np.maximum(p, _EPS))), order)

    def to_json(self) -> dict:
        return {"form": "calibrated", "f_hz": [float(x) for x in self.f_hz],
                "v_mm_s": [float(x) for x in self.v_mm_s],
                "log_c": [[float(x) for x in row] for row in self.log_c],
                "taper_mm_s": self.taper_mm_s}


def fit_calibrated(runs_by_speed: dict[float, list[tuple[Array, Array]]], fs_hz: float,
                   two: TwoPartSpectrum, *, chunk: int = CHUNK, grid_mm_s: float = 0.25
                   ) -> CalibratedSpectrum:
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
    return CalibratedSpectrum(two, np.asarray(speeds), np.vstack(rows))


def spectrum_of(model: TextureModel) -> CalibratedSpectrum:
    """The model's ``free_form`` block (checked by model_file) as a spectrum."""
    d = model.free_form
    return CalibratedSpectrum(TwoPartSpectrum.from_json(model.two_part),
                              np.asarray(d["v_mm_s"], float), np.asarray(d["log_c"], float),
                              float(d["taper_mm_s"]))
