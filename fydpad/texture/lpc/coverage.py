"""Which speeds the scans went at, and the gaps between them where a model only
interpolates (docs/texture.md, "Speed coverage"): the fit records them, ``evaluate`` and
``synth`` say when they work inside one."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad.errors import UserError

#: Speed bins of the coverage histogram (mm/s): the render smears +-1 mm/s anyway.
BIN_MM_S = 0.5
#: Seconds of steady scan a bin needs to count as scanned (a 10 s stroke leaves 0.5-4 s).
MIN_SECONDS_PER_BIN = 0.1
#: A one-bin hole between scanned spans is bridged; a gap of 1 mm/s or more is reported.
MIN_GAP_MM_S = 1.0
#: Slower is a finger at rest, not a scan (the renderer is silent below 1 mm/s).
STILL_MM_S = 1.0
#: Steady: the speed changes by less than this share of itself per second (over
#: RATE_WINDOW_S); a hand's sway is 0.5 /s at most, a stroke's start and end 3 /s and more.
STEADY_RATE_PER_S = 1.5
RATE_WINDOW_S = 0.1
#: Faster than any finger (10 m/s): left out, a corrupt sample would make a huge histogram.
MAX_SPEED_MM_S = 1e4

Span = tuple[float, float]


def steady(speed_mm_s: ArrayLike, fs_hz: float) -> NDArray[np.bool_]:
    """Samples of one speed trace whose speed changes slower than STEADY_RATE_PER_S of
    itself per second (the change over RATE_WINDOW_S, centred)."""
    v = np.asarray(speed_mm_s, float)
    half = max(1, round(RATE_WINDOW_S * fs_hz / 2))
    if v.size <= 2 * half:
        return np.zeros(v.size, bool)
    rate = np.full(v.size, np.inf)
    rate[half:-half] = np.abs(v[2 * half:] - v[:-2 * half]) * fs_hz / (2 * half)
    with np.errstate(invalid="ignore"):
        return rate <= STEADY_RATE_PER_S * np.maximum(v, STILL_MM_S)


def speed_histogram(speeds_mm_s: Iterable[ArrayLike], fs_hz: float,
                    speed_range_mm_s: tuple[float, float] | None = None
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Seconds of steady scan per ``BIN_MM_S`` bin over the speed traces: (bin edges
    from 0 mm/s, seconds). Speeds not finite, below ``STILL_MM_S``, not :func:`steady`,
    or outside ``speed_range_mm_s`` (lo <= v < hi) are left out."""
    lo, hi = speed_range_mm_s or (0.0, MAX_SPEED_MM_S)
    kept = []
    for trace in speeds_mm_s:
        v = np.asarray(trace, float).ravel()
        kept.append(v[steady(v, fs_hz) & np.isfinite(v) & (v >= max(lo, STILL_MM_S))
                      & (v < min(hi, MAX_SPEED_MM_S))])
    v = np.concatenate(kept) if kept else np.zeros(0)
    edges = np.arange(math.ceil((v.max() if v.size else 0.0) / BIN_MM_S) + 2) * BIN_MM_S
    counts, _ = np.histogram(v, edges)
    return edges, counts / fs_hz if fs_hz > 0 else np.zeros(counts.size)


def scanned_spans(speeds_mm_s: Iterable[ArrayLike], fs_hz: float,
                  speed_range_mm_s: tuple[float, float] | None = None) -> list[Span]:
    """The speed ranges (mm/s, ascending, disjoint) with at least ``MIN_SECONDS_PER_BIN``
    of steady scan per bin (:func:`speed_histogram`); holes narrower than
    ``MIN_GAP_MM_S`` bridged, the ends clipped to ``speed_range_mm_s``."""
    edges, seconds = speed_histogram(speeds_mm_s, fs_hz, speed_range_mm_s)
    spans: list[Span] = []
    for i in np.flatnonzero(seconds >= MIN_SECONDS_PER_BIN):
        lo, hi = float(edges[i]), float(edges[i + 1])
        if spans and lo - spans[-1][1] < MIN_GAP_MM_S:
            spans[-1] = (spans[-1][0], hi)
        else:
            spans.append((lo, hi))
    lo, hi = speed_range_mm_s or (0.0, math.inf)
    return [(max(a, lo), min(b, hi)) for a, b in spans]


def gaps_within(spans: Sequence[Span], lo_mm_s: float, hi_mm_s: float) -> list[Span]:
    """The parts of [lo, hi] (the fitted speeds) outside every span, at least
    ``MIN_GAP_MM_S`` wide: where a model interpolates with no scan to go by."""
    edges = [(lo_mm_s, lo_mm_s), *spans, (hi_mm_s, hi_mm_s)]
    pairs = ((max(a, lo_mm_s), min(b, hi_mm_s)) for (_, a), (b, _) in itertools.pairwise(edges))
    return [(a, b) for a, b in pairs if b - a >= MIN_GAP_MM_S]


def inside(speed_mm_s: ArrayLike, spans: Sequence[Span]) -> NDArray[np.bool_]:
    """Whether each speed lies strictly inside one of ``spans`` (boolean array)."""
    v = np.asarray(speed_mm_s, float)
    return np.any([(v > lo) & (v < hi) for lo, hi in spans] or [np.zeros(v.shape, bool)], axis=0)


def describe(spans: Sequence[Span]) -> str:
    """'12.5-17.5, 22.5-27.5 mm/s' (or 'none')."""
    return ", ".join(f"{lo:g}-{hi:g}" for lo, hi in spans) + " mm/s" if spans else "none"


def checked_spans(raw: Any, where: str, key: str) -> list[Span]:
    """``provenance[key]`` read as speed spans: a list of [lo, hi] numbers (mm/s),
    0 <= lo < hi, ascending and disjoint; UserError naming ``where`` and the key."""
    ok = isinstance(raw, list) and all(
        isinstance(p, list) and len(p) == 2 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in p) and 0 <= p[0] < p[1] for p in raw)
    spans = [(float(a), float(b)) for a, b in raw] if ok else []
    if not ok or any(b[0] < a[1] for a, b in itertools.pairwise(spans)):
        raise UserError(f"{where}: provenance.{key} must be a list of [lo, hi] speed pairs "
                        f"(mm/s, 0 <= lo < hi, ascending, disjoint), not {repr(raw)[:60]}")
    return spans


def model_gaps(provenance: dict) -> list[Span] | None:
    """The gaps a fitted model records (``provenance["interpolated_mm_s"]``, checked by
    parse_model), or None for a model without the record (unknown, not "no gaps")."""
    raw = provenance.get("interpolated_mm_s")
    return None if raw is None else [(float(a), float(b)) for a, b in raw]
