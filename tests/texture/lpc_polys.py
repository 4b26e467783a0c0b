"""Test-side polynomial helpers: known all-pole filters and their LSFs, to write HaTT
model files whose filters the tests know."""

from __future__ import annotations

import numpy as np


def reflection_to_poly(k: list[float]) -> np.ndarray:
    """Step-up recursion: A (leading 1) from reflection coefficients (|k| < 1: stable)."""
    a = np.array([1.0])
    for km in k:
        a = np.concatenate([a, [0.0]]) + km * np.concatenate([[0.0], a[::-1]])
    return a


def poly_to_lsf(a: np.ndarray) -> np.ndarray:
    """Sorted LSFs (rad, in (0, pi)) of a stable low-order A: the angles of the zeros of
    P, Q = A(z) +- z^-(p+1) A(1/z), the fixed ones at z = +-1 left out."""
    ext = np.concatenate([np.asarray(a, float), [0.0]])
    w = np.angle(np.concatenate([np.roots(ext + ext[::-1]), np.roots(ext - ext[::-1])]))
    return np.sort(w[(w > 1e-6) & (w < np.pi - 1e-6)])
