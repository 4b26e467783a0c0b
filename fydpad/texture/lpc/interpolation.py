"""The LPC model between its fitted speeds, as the model file's ``interpolation`` names:
``"nearest"``, the nearest fitted model unchanged (the paper's per-speed fits, III-B);
``"stretch"``, the all-pole fit of the calibrated spectrum S(f, v) at the speed."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.texture.lpc.analysis import is_stable
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.spectrum import spectrum_of

Array = NDArray[np.float64]


class SpeedInterpolator:
    """(A, sigma^2) at any speed from a model, by the model's ``interpolation``."""

    def __init__(self, model: TextureModel):
        self.model = model  # parse_model checked its interpolation and spectrum
        self._spectrum = spectrum_of(model) if model.interpolation == "stretch" else None

    def __call__(self, speed_mm_s: float) -> tuple[Array, float]:
        m = self.model
        if self._spectrum is not None:
            return self._spectrum.ar(speed_mm_s, m.order, m.fs_hz)
        i = int(np.argmin(np.abs(m.speeds_mm_s - speed_mm_s)))
        return m.poly(i), float(m.sigma2[i])


@dataclass
class SpeedTable:
    """Filters on a fine speed grid, so the 1 kHz loop only looks them up: ``h[i]``,
    ``sigma[i]`` (the std of e, eq. 5) and ``stable[i]`` at ``speeds_mm_s[i]``."""

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


def table_range(model: TextureModel) -> tuple[float, float]:
    """The speeds a table covers (clamped beyond): the nearest models' fitted speeds; the
    spectrum's, every speed its fit saw, down to the renderer's fade (the slowest less the
    tolerance, at least half of it) and up to the fastest plus the tolerance."""
    lo, hi = float(model.speeds_mm_s[0]), float(model.speeds_mm_s[-1])
    if model.interpolation == "stretch":
        tol = float(model.tolerance_mm_s)
        return max(lo - tol, 0.5 * lo), hi + tol
    return lo, hi


def build_table(model: TextureModel, step_mm_s: float = 0.25) -> SpeedTable:
    """The model at every ``step_mm_s`` of :func:`table_range`, anchored at its slowest speed."""
    interp = SpeedInterpolator(model)
    v0 = float(model.speeds_mm_s[0])
    lo, hi = table_range(model)
    lo = v0 - step_mm_s * math.floor((v0 - lo) / step_mm_s + 1e-9)
    n = math.floor((hi - lo) / step_mm_s + 1e-9) + 1
    grid = lo + step_mm_s * np.arange(n)
    polys = np.empty((n, model.order + 1))
    s2 = np.empty(n)
    for k, v in enumerate(grid):
        polys[k], s2[k] = interp(float(v))
    stable = np.array([is_stable(a) for a in polys])
    return SpeedTable(grid, polys, -polys[:, 1:], np.sqrt(s2), stable, step_mm_s)
