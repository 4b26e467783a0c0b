"""Which speeds the scans went at, and where a model only interpolates (docs/texture.md,
"Speed coverage: where a model interpolates").

A model is measured only where the scans' strokes went. A hand asked for 10 mm/s
wanders about 8.5-11.5 mm/s, so strokes at the paper's 10, 20, 30 and 40 mm/s leave
gaps about 5 mm/s wide between them. Inside a gap the spectrum is the spectral model's
interpolation, and on held-out strokes it is measurably less accurate there than at the
scanned speeds (15 mm/s against 10 and 20 in docs/texture.md). The fit records the gaps
so that a lab knows where to scan more. ``evaluate`` and ``synth`` then say when they
work inside a gap.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from fydpad.errors import UserError

#: Speed bins of the coverage histogram (mm/s): the render smears +-1 mm/s anyway.
BIN_MM_S = 0.5
#: Seconds of scan a bin needs to count as scanned. A stroke's start and end sweep
#: through every slower speed in a few ms per bin; a hand's wander around its target
#: stays 0.5-3 s per bin (the generator's 10 s strokes at 10-40 mm/s).
MIN_SECONDS_PER_BIN = 0.1
#: Narrower gaps between scanned spans are bridged (two bins: within the render's smear).
MIN_GAP_MM_S = 1.0
#: Slower is a finger at rest, not a scan (the renderer is silent below its still_mm_s,
#: 1 mm/s by default); a stroke's start and end dwell there.
STILL_MM_S = 1.0

Span = tuple[float, float]


def speed_histogram(speeds_mm_s: Iterable[ArrayLike], fs_hz: float,
                    speed_range_mm_s: tuple[float, float] | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Seconds of scan per ``BIN_MM_S`` bin: (bin edges from 0 mm/s, seconds). NaN speeds
    (a lost track), speeds below ``STILL_MM_S`` (at rest) and, if given, speeds outside
    ``speed_range_mm_s`` are left out."""
    v = np.concatenate([np.asarray(s, float).ravel() for s in speeds_mm_s] or [np.zeros(0)])
    ok = np.isfinite(v) & (v >= STILL_MM_S)
    if speed_range_mm_s is not None:
        ok &= (v >= speed_range_mm_s[0]) & (v <= speed_range_mm_s[1])
    counts = np.bincount(np.floor(v[ok] / BIN_MM_S).astype(np.int64))
    seconds = counts / fs_hz if fs_hz > 0 else np.zeros(0)
    return np.arange(seconds.size + 1) * BIN_MM_S, seconds


def scanned_spans(speeds_mm_s: Iterable[ArrayLike], fs_hz: float,
                  speed_range_mm_s: tuple[float, float] | None = None,
                  min_seconds_per_bin: float = MIN_SECONDS_PER_BIN) -> list[Span]:
    """The speed ranges (mm/s, ascending, disjoint) in which the speed traces spent at
    least ``min_seconds_per_bin`` per ``BIN_MM_S`` bin (:func:`speed_histogram`'s
    speeds). Gaps narrower than ``MIN_GAP_MM_S`` are bridged."""
    edges, seconds = speed_histogram(speeds_mm_s, fs_hz, speed_range_mm_s)
    spans: list[Span] = []
    for i in np.flatnonzero(seconds >= min_seconds_per_bin):
        lo, hi = float(edges[i]), float(edges[i + 1])
        if spans and lo - spans[-1][1] < MIN_GAP_MM_S:
            spans[-1] = (spans[-1][0], hi)
        else:
            spans.append((lo, hi))
    return spans


def gaps_between(spans: Sequence[Span]) -> list[Span]:
    """The speed ranges between scanned spans: where a model interpolates."""
    return [(a[1], b[0]) for a, b in itertools.pairwise(spans)]


def inside(speed_mm_s: ArrayLike, spans: Sequence[Sequence[float]]) -> np.ndarray:
    """Whether each speed lies strictly inside one of ``spans`` (boolean array)."""
    v = np.asarray(speed_mm_s, float)
    out = np.zeros(v.shape, bool)
    for lo, hi in spans:
        out |= (v > lo) & (v < hi)
    return out


def describe(spans: Sequence[Sequence[float]]) -> str:
    """'12.5-17.5, 22.5-27.5 mm/s' (or 'none')."""
    if not spans:
        return "none"
    return ", ".join(f"{lo:g}-{hi:g}" for lo, hi in spans) + " mm/s"


def model_gaps(provenance: dict, where: str = "model") -> list[Span]:
    """The gaps a fitted model records (``provenance["interpolated_mm_s"]``: [[lo, hi],
    ...]; files fitted before coverage was recorded have none). UserError naming
    ``where`` and the field when it is malformed."""
    raw = provenance.get("interpolated_mm_s")
    if raw is None:
        return []
    try:
        gaps = [(float(a), float(b)) for a, b in raw]
    except (TypeError, ValueError):
        gaps = None
    if gaps is None or not all(np.isfinite(a) and np.isfinite(b) and a < b for a, b in gaps):
        raise UserError(f"{where}: provenance.interpolated_mm_s must be a list of [lo, hi] "
                        f"speed pairs (mm/s, lo < hi), not {str(raw)[:60]}")
    return gaps
