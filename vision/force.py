"""Load cell force (Phidgets CZL616C, 0-780 g, paper II-A): raw ADC counts to newtons,
saturation flags, and the calibration of offset and gain from known weights.

``force_n = gain_n_per_count * (raw - offset_counts)``. A reading at or beyond full
scale (780 g = 7.65 N), or at the ADC's rails, is flagged saturated: the true force
may be larger than the number says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.config import G_M_S2, ForceConfig
from vision.errors import UserError


@dataclass
class ForceReading:
    """Forces in N (NaN where the raw value is missing) and their saturation flags."""

    force_n: NDArray[np.float64]
    saturated: NDArray[np.bool_]


def raw_to_force(raw: ArrayLike, config: ForceConfig | None = None) -> ForceReading:
    """Counts to newtons with the calibrated offset and gain; flags saturation."""
    c = config or ForceConfig()
    r = np.asarray(raw, dtype=np.float64)
    f = c.gain_n_per_count * (r - c.offset_counts)
    return ForceReading(f, saturation_flags(f, r, c))


def saturation_flags(
    force_n: ArrayLike, raw: ArrayLike | None = None, config: ForceConfig | None = None,
) -> NDArray[np.bool_]:
    """At or beyond full scale (either sign: an overload pulls the bridge both ways), or
    at the ADC's rails, where the number no longer follows the force."""
    c = config or ForceConfig()
    f = np.asarray(force_n, dtype=np.float64)
    # A hair below full scale: a full-scale weight read back with noise still counts.
    sat = np.abs(f) >= c.full_scale_n * (1 - 1e-9)
    if raw is not None:
        r = np.asarray(raw, dtype=np.float64)
        sat |= (r <= c.raw_min) | (r >= c.raw_max)
    return sat


class ForceCalibrationError(UserError, ValueError):
    """Calibration data is too little or degenerate; the message says why."""


@dataclass
class ForceCalibration:
    """The fit of ``force = gain * (raw - offset)`` to readings under known weights."""

    offset_counts: float
    gain_n_per_count: float
    r2: float
    residuals_n: NDArray[np.float64]
    n_points: int

    @property
    def rms_residual_n(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_n**2)))

    def config(self, full_scale_g: float = 780.0) -> ForceConfig:
        return ForceConfig(offset_counts=self.offset_counts,
                           gain_n_per_count=self.gain_n_per_count, full_scale_g=full_scale_g)


def calibrate_force(
    mass_g: ArrayLike, raw: ArrayLike, full_scale_g: float = 780.0,
) -> ForceCalibration:
    """Least squares of the weights' forces (m g) on the raw readings.

    Needs at least two distinct weights (one of them may be 0 g, the empty cell) and
    readings that change with the weight. Weights above full scale are refused: the
    cell is not linear there and may be damaged.
    """
    m = np.asarray(mass_g, dtype=np.float64)
    r = np.asarray(raw, dtype=np.float64)
    if m.shape != r.shape or m.ndim != 1:
        raise ForceCalibrationError("masses and readings must be two lists of equal length")
    if m.size < 3:
        raise ForceCalibrationError(f"need at least 3 readings, got {m.size}")
    if np.unique(m).size < 2:
        raise ForceCalibrationError("need at least two different weights")
    if np.any(m < 0) or np.any(m > full_scale_g):
        raise ForceCalibrationError(f"weights must be within 0-{full_scale_g:g} g (full scale)")
    if np.ptp(r) == 0:
        raise ForceCalibrationError("the readings do not change with the weight "
                                    "(load cell disconnected?)")
    f = m * 1e-3 * G_M_S2
    a = np.column_stack([r, np.ones_like(r)])
    (slope, intercept), *_ = np.linalg.lstsq(a, f, rcond=None)
    if slope == 0:
        raise ForceCalibrationError("the fitted gain is zero")
    resid = f - (slope * r + intercept)
    ss_tot = float(np.sum((f - f.mean()) ** 2))
    r2 = 1.0 - float(np.sum(resid**2)) / ss_tot
    return ForceCalibration(
        offset_counts=float(-intercept / slope), gain_n_per_count=float(slope), r2=r2,
        residuals_n=resid, n_points=int(m.size),
    )
