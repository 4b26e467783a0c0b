"""Interpolating LPC models over speed (paper III-B: "the two closest entries in speed").

Methods:

- ``"nearest"``: the model of the nearest fitted speed, unchanged (the paper's per-speed
  fits on a fine speed grid: no coefficients are interpolated).
- ``"stretch"`` (default): the fitted model unchanged near its own speed, and between
  the fitted speeds both neighbours' spectra moved along the frequency axis with speed
  (a surface's features sound at speed / wavelength), mixed and refitted
  (``speed_warp.py``). Every filter is a Levinson fit to a positive spectrum: stable.
- ``"lsf"``: line spectral frequencies interpolated linearly, sigma^2
  geometrically. Sorted LSFs stay sorted under a convex combination, so every
  interpolated filter is stable, and spectral peaks glide in frequency as the speed
  changes instead of cross-fading.
- ``"reflection"``: reflection coefficients interpolated linearly (|k| < 1 is convex:
  also always stable), sigma^2 geometrically.
- ``"linear"``: the paper's way: h and sigma^2 interpolated linearly. Not guaranteed
  stable at order 200; kept to compare against.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.texture.lpc import is_stable, poly_to_reflection, reflection_to_poly
from fydpad.texture.lsf import lsf_to_poly, poly_to_lsf
from fydpad.texture.model_file import TextureModel
from fydpad.texture.speed_warp import SpeedWarp
from fydpad.texture.two_part import TwoPartSpectrum

Array = NDArray[np.float64]
METHODS = ("nearest", "stretch", "lsf", "reflection", "linear")
#: What every path renders unless told otherwise: None, the model file's ``interpolation``.
DEFAULT_METHOD: str | None = None
HOLD_FRACTION = 0.3


def bracket(speeds_mm_s: Array, speed_mm_s: float) -> tuple[int, int, float]:
    """Indices of the two nearest model speeds and the weight of the upper one (clamped)."""
    s = np.asarray(speeds_mm_s, float)
    if speed_mm_s <= s[0] or s.size == 1:
        return 0, 0, 0.0
    if speed_mm_s >= s[-1]:
        return s.size - 1, s.size - 1, 0.0
    j = int(np.searchsorted(s, speed_mm_s))
    i = j - 1
    return i, j, float((speed_mm_s - s[i]) / (s[j] - s[i]))


class SpeedInterpolator:
    """Interpolated (A, sigma^2) at any speed from a model's table, by ``method``."""

    def __init__(self, model: TextureModel, method: str | None = None,
                 hold_mm_s: float | None = None):
        method = model.interpolation if method is None else method
        if method not in METHODS:
            raise ValueError(f"interpolation method must be one of {METHODS}, not {method!r}")
        self.model = model
        self.method = method
        self.polys = np.vstack([model.poly(i) for i in range(len(model.speeds_mm_s))])
        self._two = None
        if method == "stretch" and model.free_form is not None:
            # A speed-resolved spectrum (free_form.py) at any speed; imported here because
            # free_form builds on this module's neighbours.
            from fydpad.texture.free_form import spectrum_of

            self._two = spectrum_of(model)
        elif method == "stretch" and model.two_part is not None:
            # The two-part model gives the spectrum at any speed itself (two_part.py).
            self._two = TwoPartSpectrum.from_json(model.two_part)
        elif method == "stretch":
            # Near its speed the fitted model is kept (see speed_warp): 30 % of the fit
            # tolerance, the value that scored best on the generator's strokes (docs).
            hold = HOLD_FRACTION * model.tolerance_mm_s if hold_mm_s is None else hold_mm_s
            if hold_mm_s is None and model.provenance.get("speed_normalised"):
                hold = 0.0  # a model at its exact speed: nothing to hold (fit.py)
            self._warp = SpeedWarp(model.speeds_mm_s, self.polys, model.sigma2, model.fs_hz,
                                   model.fit_band_hz, hold)
        if method == "lsf":
            try:
                self.params = np.vstack([poly_to_lsf(a) for a in self.polys])
            except ValueError:
                # LSFs need |A| within ~1e12 of its peak on the unit circle (the FFT sign
                # test); a fit with a noise floor always is. Otherwise reflection
                # coefficients, equally stable.
                warnings.warn(f"{model.surface}: LSFs not resolvable, interpolating "
                              "reflection coefficients instead", stacklevel=2)
                method = self.method = "reflection"
        if method == "reflection":
            self.params = np.vstack([poly_to_reflection(a) for a in self.polys])
        elif method == "linear":
            self.params = self.polys

    def __call__(self, speed_mm_s: float) -> tuple[Array, float]:
        if self._two is not None:
            return self._two.ar(speed_mm_s, self.model.order, self.model.fs_hz)
        if self.method == "stretch":
            return self._warp(speed_mm_s)
        m = self.model
        if self.method == "nearest":
            i = int(np.argmin(np.abs(m.speeds_mm_s - speed_mm_s)))
            return self.polys[i].copy(), float(m.sigma2[i])
        i, j, w = bracket(m.speeds_mm_s, speed_mm_s)
        if i == j or w == 0.0:
            return self.polys[i].copy(), float(m.sigma2[i])
        p = (1.0 - w) * self.params[i] + w * self.params[j]
        if self.method == "linear":
            return p, float((1.0 - w) * m.sigma2[i] + w * m.sigma2[j])
        s2 = float(np.exp((1.0 - w) * np.log(m.sigma2[i]) + w * np.log(m.sigma2[j])))
        a = lsf_to_poly(p) if self.method == "lsf" else reflection_to_poly(p)
        return a, s2


@dataclass
class SpeedTable:
    """Filters precomputed on a fine speed grid, so the 1 kHz loop only looks them up.

    ``h[i]`` and ``sigma[i]`` (standard deviation of e, eq. 5) belong to speed
    ``speeds_mm_s[i]``; ``stable[i]`` is the check of each entry.
    """

    speeds_mm_s: Array
    polys: Array
    h: Array
    sigma: Array
    stable: NDArray[np.bool_]
    step_mm_s: float

    def index(self, speed_mm_s: float) -> int:
        """Nearest grid entry (clamped to the table)."""
        i = int((speed_mm_s - self.speeds_mm_s[0]) / self.step_mm_s + 0.5)
        return 0 if i < 0 else (self.h.shape[0] - 1 if i >= self.h.shape[0] else i)


def table_range(model: TextureModel, method: str | None = None) -> tuple[float, float]:
    """The speeds a table covers (clamped beyond). A speed-resolved spectrum (two-part,
    free-form) is rendered at every speed its fit saw: down to where the renderer starts
    fading (the slowest speed less the fit tolerance, at least half of it) and up to the
    fastest plus the tolerance. Otherwise the slowest and fastest models, held beyond: each
    was fitted on the runs within the tolerance of its speed, wander and all.

    Why: the spectrum *at* 10 mm/s held down to 5 puts 10's level on 5-10 mm/s (measured
    on 12 s held-out strokes at 40 mm/s, seed set A: felt +2.42 -> +0.33 dB over the
    ceiling, cork +1.96 -> -0.01, brick +4.01 -> +1.10)."""
    lo, hi = float(model.speeds_mm_s[0]), float(model.speeds_mm_s[-1])
    method = model.interpolation if method is None else method
    if method == "stretch" and (model.free_form is not None or model.two_part is not None):
        tol = float(model.tolerance_mm_s)
        return max(lo - tol, 0.5 * lo), hi + tol
    return lo, hi


def build_table(model: TextureModel, method: str | None = None, step_mm_s: float = 0.25,
                hold_mm_s: float | None = None) -> SpeedTable:
    """Interpolate the model at every ``step_mm_s`` over :func:`table_range` (the grid is
    anchored at the slowest fitted speed)."""
    interp = SpeedInterpolator(model, method, hold_mm_s)
    v0 = float(model.speeds_mm_s[0])
    lo, hi = table_range(model, method)
    lo = v0 - step_mm_s * math.floor((v0 - lo) / step_mm_s + 1e-9)
    n = math.floor((hi - lo) / step_mm_s + 1e-9) + 1
    grid = lo + step_mm_s * np.arange(n)
    polys = np.empty((n, model.order + 1))
    s2 = np.empty(n)
    for k, v in enumerate(grid):
        polys[k], s2[k] = interp(float(v))
    stable = np.array([is_stable(a) for a in polys])
    return SpeedTable(grid, polys, -polys[:, 1:], np.sqrt(s2), stable, step_mm_s)


