"""Speed segmentation (paper III-B): windows whose speed stays near a target speed."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

DEFAULT_SPEEDS_MM_S = (10.0, 20.0, 30.0, 40.0)
DEFAULT_TOLERANCE_MM_S = 5.0


def runs(mask: ArrayLike, min_len: int = 1) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of ``mask`` at least ``min_len`` long."""
    m = np.asarray(mask, bool).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], m, [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2], strict=True)
            if b - a >= min_len]


def segment_by_speed(
    speed_mm_s: ArrayLike, fs_hz: float, targets_mm_s: ArrayLike = DEFAULT_SPEEDS_MM_S,
    tolerance_mm_s: float = DEFAULT_TOLERANCE_MM_S, min_seconds: float = 0.25,
) -> dict[float, list[tuple[int, int]]]:
    """For each target speed, the runs where |speed - target| <= tolerance (paper: 5 mm/s).

    Runs shorter than ``min_seconds`` are dropped: they carry too little of the surface
    to estimate a spectrum.
    """
    v = np.asarray(speed_mm_s, float)
    min_len = max(1, round(min_seconds * fs_hz))
    return {float(s): runs(np.abs(v - s) <= tolerance_mm_s, min_len)
            for s in np.asarray(targets_mm_s, float)}
