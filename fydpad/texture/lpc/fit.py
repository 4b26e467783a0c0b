"""Fitting the LPC family's two forms from scans (Bianchi 2015 Fig. 8): the paper's
per-speed LPC (:func:`fit_paper`) and the calibrated spectrum (:func:`fit_texture`)."""

from __future__ import annotations

import datetime as _dt
import math
import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.family import runs
from fydpad.texture.lpc.analysis import (
    DEFAULT_SPEEDS_MM_S,
    DEFAULT_TOLERANCE_MM_S,
    h_from_poly,
    is_stable,
    lpc_autocorrelation,
)
from fydpad.texture.lpc.coverage import Span, gaps_within, scanned_spans
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.spectrum import ITERATIONS, PREWHITEN_ORDER, fit_calibrated, fit_two_part
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]
#: The plain fit's grid step: the nearest grid speed is never more than half a step away.
PAPER_GRID_STEP_MM_S = 1.0
#: Where fewer samples lie within the window of a speed, the nearest this many seconds.
PAPER_MIN_SECONDS = 2.0


def _prepare(scans: list[Scan], highpass_hz: float) -> tuple[float, list[tuple[Array, Array]]]:
    """The scans' rate and each scan's modelling signal (high-pass, DFT321) and speed."""
    if not scans:
        raise UserError("no scans to fit")
    fs = scans[0].fs_hz
    for scan in scans:
        if abs(scan.fs_hz - fs) > 1e-6 * fs:
            raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz differs "
                            f"from the first scan's {fs:g} Hz")
    return fs, [(preprocess(sc.acc, fs, highpass_hz), np.asarray(sc.speed_mm_s, float))
                for sc in scans]


def _where(scans: list[Scan]) -> str:
    return scans[0].path if len(scans) == 1 else "scans"


def _model(scans: list[Scan], fs: float, speeds: Sequence[float],
           fits: Sequence[tuple[Array, float, int]], method: dict[str, Any],
           spans: list[Span], gaps: list[Span], surface: str | None, highpass_hz: float,
           **fields: Any) -> TextureModel:
    """The model of per-speed fits (A, sigma^2, samples) and its provenance: the scans,
    the ``method`` and its settings, the samples per speed and where the scans went."""
    provenance = {
        "scans": [s.path for s in scans], **method, "tool": "fydpad texture fit",
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "samples_per_speed": {f"{v:g}": n for v, (_, _, n) in zip(speeds, fits, strict=True)},
        "speed_coverage_mm_s": [list(sp) for sp in spans],
        "interpolated_mm_s": [list(g) for g in gaps],
    }
    return TextureModel(
        surface=surface or scans[0].surface, fs_hz=fs, speeds_mm_s=np.asarray(speeds),
        h=np.vstack([h_from_poly(a) for a, _, _ in fits]),
        sigma2=np.asarray([s2 for _, s2, _ in fits]), highpass_hz=highpass_hz,
        fit_band_hz=(highpass_hz, fs / 2), provenance=provenance, **fields)


def fit_texture(
    scans: Iterable[Scan], *, order: int = 200, speeds_mm_s: Sequence[float] = DEFAULT_SPEEDS_MM_S,
    tolerance_mm_s: float = DEFAULT_TOLERANCE_MM_S, highpass_hz: float = 10.0,
    min_seconds: float = 0.25, surface: str | None = None,
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0),
    wrap_iterations: Callable[[Iterable], Iterable] = lambda it: it,
) -> TextureModel:
    """The calibrated form (:mod:`spectrum`): S = S_two(f, v), fitted on every 0.5 s chunk,
    times a correction measured at each target speed with data (two or more) on its runs
    of ``min_seconds`` within ``tolerance_mm_s``; (h, sigma^2) the all-pole fit of S there.
    ``wrap_iterations`` wraps the two-part fit's iterations (a progress bar)."""
    scans = list(scans)
    fs, prepared = _prepare(scans, highpass_hz)
    by: dict[float, list[tuple[Array, Array]]] = {float(s): [] for s in speeds_mm_s}
    min_len = max(1, round(min_seconds * fs))  # shorter: too little for a spectrum
    for x, v in prepared:
        for s, segs in by.items():
            segs.extend((x[r0:r1], v[r0:r1])
                        for r0, r1 in runs(np.abs(v - s) <= tolerance_mm_s, min_len))
    counts = {s: sum(x.size for x, _ in segs) for s, segs in by.items()}
    for s in (s for s, n in counts.items() if n == 0):
        warnings.warn(f"no scan has {min_seconds:g} s within {tolerance_mm_s:g} mm/s of "
                      f"{s:g} mm/s: no model at that speed", stacklevel=2)
    short = [f"only {n} samples near {s:g} mm/s for an order-{order} model (need at least "
             f"{4 * order}); record longer or lower --order"
             for s, n in counts.items() if 0 < n < 4 * order]
    got = [s for s, n in counts.items() if n >= 4 * order]
    if not got and short:
        raise UserError(f"{_where(scans)}: {short[0]}")
    for msg in short:
        warnings.warn(f"{msg}: no model at that speed", stacklevel=2)
    if len(got) < 2:
        raise UserError(f"{_where(scans)}: the calibrated form needs two or more target "
                        f"speeds with data, these have {len(got)} (column 'speed_mm_s'); "
                        "fit with --form paper")
    lo, hi = modelled_speed_range(got, tolerance_mm_s)
    try:
        two = fit_two_part([x for x, _ in prepared], [v for _, v in prepared], fs, (lo, hi),
                           ITERATIONS, wrap=wrap_iterations)
        spec = fit_calibrated({s: by[s] for s in got}, two)
    except ValueError as exc:
        raise UserError(f"calibrated spectrum: {exc}") from None
    fits = [(*spec.ar(s, order, fs), counts[s]) for s in got]
    if not all(is_stable(a) for a, _, _ in fits):
        raise UserError("spectral model: an all-pole fit of S(f, v) is unstable")
    spans = scanned_spans([v for _, v in prepared], fs, (lo, hi))
    method = {"method": "two-stage all-pole fit of S(f, v)", "order": order,
              "prewhiten_order": PREWHITEN_ORDER}
    model = _model(scans, fs, got, fits, method, spans, gaps_within(spans, min(got), max(got)),
                   surface, highpass_hz, drive_band_hz=drive_band_hz,
                   tolerance_mm_s=tolerance_mm_s, interpolation="stretch",
                   two_part=two.to_json(), free_form=spec.to_json())
    model.provenance.update(spectral_model="free-form", two_part_iterations=ITERATIONS,
                            form="calibrated")
    return model


def modelled_speed_range(speeds_mm_s: Sequence[float], tolerance_mm_s: float
                         ) -> tuple[float, float]:
    """The speeds a fit over ``speeds_mm_s`` reads: each within the tolerance, above 0.5."""
    return max(min(speeds_mm_s) - tolerance_mm_s, 0.5), max(speeds_mm_s) + tolerance_mm_s


def fit_paper(
    scans: Iterable[Scan], *, order: int = 200, tolerance_mm_s: float = DEFAULT_TOLERANCE_MM_S,
    highpass_hz: float = 10.0, surface: str | None = None,
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0),
) -> TextureModel:
    """The paper's method read plainly (Fig. 8, eq. 4): every ``PAPER_GRID_STEP_MM_S`` over
    the scanned speeds (1st-99th percentile of the moving samples), one LPC of ``order``
    (autocorrelation method) on the samples within ``tolerance_mm_s`` of the speed, or the
    ``PAPER_MIN_SECONDS`` nearest where fewer; rendered by the nearest grid speed."""
    scans = list(scans)
    fs, prepared = _prepare(scans, highpass_hz)
    vs = [v for _, v in prepared]
    v_all = np.concatenate(vs)
    moving = v_all[v_all > 1.0]
    step_mm_s = PAPER_GRID_STEP_MM_S
    need = round(PAPER_MIN_SECONDS * fs)
    if moving.size < max(need, 4 * order):
        raise UserError(f"{_where(scans)}: only {moving.size} moving samples (speed > 1 mm/s) "
                        f"for an order-{order} model (need {max(need, 4 * order)}); record "
                        "longer or lower --order")
    lo, hi = np.percentile(moving, [1, 99])
    lo = max(step_mm_s * math.floor(lo / step_mm_s), step_mm_s)
    grid = lo + step_mm_s * np.arange(math.floor((hi - lo) / step_mm_s + 1e-9) + 1)
    fits = []
    for v in grid:
        dist = np.abs(v_all - v)
        limit = tolerance_mm_s
        if np.count_nonzero(dist <= limit) < need:
            limit = float(np.partition(dist, need - 1)[need - 1])
        segs = [x[a:b] for x, sv in prepared for a, b in runs(np.abs(sv - v) <= limit, 1)]
        for floor in (1e-9, 1e-7, 1e-5, 1e-3):
            # Rounding can make an order-200 fit of a 60 dB spectrum unstable; a floor mends it.
            a, s2 = lpc_autocorrelation(segs, order, floor)
            if is_stable(a):
                break
        else:
            raise UserError(f"speed {v:g} mm/s: the fitted filter is unstable")
        fits.append((a, s2, int(sum(s.size for s in segs))))
    spans = scanned_spans(vs, fs, (float(grid[0]) - tolerance_mm_s,
                                   float(grid[-1]) + tolerance_mm_s))
    method = {"method": "autocorrelation", "order": order, "form": "paper",
              "window_mm_s": tolerance_mm_s, "min_seconds": PAPER_MIN_SECONDS}
    return _model(scans, fs, grid, fits, method, spans, [], surface, highpass_hz,
                  drive_band_hz=drive_band_hz, tolerance_mm_s=step_mm_s / 2,
                  interpolation="nearest")
