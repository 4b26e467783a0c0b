"""Eq. (1) of Bianchi 2015 for one sensor, written out independently of
``vision.indentation.sensor_distances_mm`` (which the library uses), as the tests' reference."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.ir import PAPER_POLY_CM, VALID_VOLTAGE_RANGE_V


def voltage_to_distance_mm(
    voltage_v: ArrayLike,
    poly_cm: ArrayLike = PAPER_POLY_CM,
    valid_range_v: tuple[float, float] = VALID_VOLTAGE_RANGE_V,
) -> NDArray[np.float64]:
    """Distance in mm from sensor voltage (the fit is in cm); NaN out of the valid range."""
    v = np.asarray(voltage_v, dtype=np.float64)
    d_mm = np.polyval(np.asarray(poly_cm, dtype=np.float64), v) * 10.0
    valid = (v >= valid_range_v[0]) & (v <= valid_range_v[1])
    return np.where(valid, d_mm, np.nan)
