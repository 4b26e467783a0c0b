"""Fitting a speed-indexed LPC texture model from scans (paper Fig. 8)."""

from __future__ import annotations

import datetime as _dt
import math
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.lpc.analysis import (
    DEFAULT_SPEEDS_MM_S,
    DEFAULT_TOLERANCE_MM_S,
    h_from_poly,
    is_stable,
    lpc_autocorrelation,
    segment_by_speed,
)
from fydpad.texture.lpc.analysis import runs as segment_runs
from fydpad.texture.lpc.coverage import gaps_within, scanned_spans
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.lines import LineFit, fit_lines
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.spectrum import ITERATIONS, PREWHITEN_ORDER, fit_calibrated, fit_two_part
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]


@dataclass
class FitReport:
    """What each speed's fit used and produced."""

    speed_mm_s: float
    n_samples: int
    n_segments: int
    sigma2: float
    signal_var: float
    stable: bool


def fit_texture(
    scans: Iterable[Scan], *, order: int = 200, speeds_mm_s: Sequence[float] = DEFAULT_SPEEDS_MM_S,
    tolerance_mm_s: float = DEFAULT_TOLERANCE_MM_S, highpass_hz: float = 10.0,
    min_seconds: float = 0.25, surface: str | None = None,
    lines: str | float | None = "auto",
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0),
    wrap: Callable[[Iterable], Iterable] = lambda it: it,
    wrap_iterations: Callable[[Iterable], Iterable] = lambda it: it,
) -> tuple[TextureModel, list[FitReport]]:
    """The calibrated form (:mod:`spectrum`): the two-part spectrum S_two(f, v) fitted on
    every 0.5 s chunk within the modelled speeds, times a correction C_i measured at each
    target speed on the runs within ``tolerance_mm_s`` of it; each speed's (h, sigma^2)
    is the all-pole fit of S there. Each scan is high-passed at ``highpass_hz`` and
    reduced by DFT321 as a whole; a periodic surface's lines (:mod:`lines`) are fitted
    first and the spectrum on what they leave. Needs two or more target speeds with
    data. ``wrap`` wraps the scans, ``wrap_iterations`` the two-part fit's iterations.
    """
    scans = list(scans)
    if not scans:
        raise UserError("no scans to fit")
    fs = scans[0].fs_hz
    prepared: list[tuple[Array, Array]] = []
    for scan in wrap(scans):
        if abs(scan.fs_hz - fs) > 1e-6 * fs:
            raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz differs "
                            f"from the first scan's {fs:g} Hz")
        prepared.append((preprocess(scan.acc, fs, highpass_hz), scan.speed_mm_s))
    line_fit = _fit_lines(prepared, fs, speeds_mm_s, tolerance_mm_s, lines)
    pooled: dict[float, list[Array]] = {float(s): [] for s in speeds_mm_s}
    whole: list[tuple[Array, Array]] = []
    speeds_of: dict[float, list[Array]] = {float(s): [] for s in speeds_mm_s}
    for i, (x, v) in enumerate(prepared):
        pieces = [(0, x.size)]
        if line_fit.spectrum is not None:
            # What the lines leave, where they could be taken out (see lines.fit_lines).
            x = line_fit.residuals[i]
            pieces = segment_runs(line_fit.keep[i], 1)
        for a, b in pieces:
            whole.append((x[a:b], v[a:b]))
            for s, rs in segment_by_speed(v[a:b], fs, speeds_mm_s, tolerance_mm_s,
                                          min_seconds).items():
                pooled[s].extend(x[a + r0:a + r1] for r0, r1 in rs)
                speeds_of[s].extend(v[a + r0:a + r1] for r0, r1 in rs)
    got_speeds, reports = [], []
    short: list[str] = []  # speeds with data, too little for the order
    for s, segs in pooled.items():
        n = sum(seg.size for seg in segs)
        if n == 0:
            warnings.warn(f"no scan has {min_seconds:g} s within {tolerance_mm_s:g} mm/s of "
                          f"{s:g} mm/s: no model at that speed", stacklevel=2)
            continue
        if n < 4 * order:
            short.append(f"only {n} samples near {s:g} mm/s for an order-{order} model "
                         f"(need at least {4 * order}); record longer or lower --order")
            continue
        got_speeds.append(s)
        sv = float(np.mean(np.concatenate(segs) ** 2))
        reports.append(FitReport(s, n, len(segs), 0.0, sv, True))
    if not got_speeds and short:
        raise UserError(f"{scans[0].path if len(scans) == 1 else 'scans'}: {short[0]}")
    for msg in short:
        warnings.warn(f"{msg}: no model at that speed", stacklevel=2)
    if len(got_speeds) < 2:
        raise UserError(f"{scans[0].path if len(scans) == 1 else 'scans'}: the calibrated "
                        f"form needs two or more target speeds with data, these have "
                        f"{len(got_speeds)} (column 'speed_mm_s'); fit with --form paper")
    spectral = _fit_spectrum(whole, pooled, speeds_of, got_speeds, fs, order, tolerance_mm_s,
                             wrap_iterations)
    hs, sig = spectral.hs, spectral.sigma2
    reports = [replace(r, sigma2=float(s2)) for r, s2 in zip(reports, sig, strict=True)]
    model = TextureModel(
        surface=surface or scans[0].surface, fs_hz=fs, speeds_mm_s=np.asarray(got_speeds),
        h=np.vstack(hs), sigma2=np.asarray(sig), highpass_hz=highpass_hz,
        fit_band_hz=(highpass_hz, fs / 2), drive_band_hz=drive_band_hz,
        tolerance_mm_s=tolerance_mm_s, interpolation="stretch",
        provenance={
            "scans": [s.path for s in scans],
            # models[] are the all-pole fits of S at the fitted speeds (spectrum.py)
            "method": "two-stage all-pole fit of S(f, v)", "order": order,
            "prewhiten_order": PREWHITEN_ORDER,
            "tool": "fydpad texture fit",
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "samples_per_speed": {f"{r.speed_mm_s:g}": r.n_samples for r in reports},
        },
    )
    # Where the strokes the model was fitted on went, and where it only interpolates
    # (coverage.py): the spectrum reads every chunk within the modelled speeds.
    spans = scanned_spans([v for _, v in prepared], fs,
                          modelled_speed_range(got_speeds, tolerance_mm_s))
    model.provenance["speed_coverage_mm_s"] = [list(sp) for sp in spans]
    model.provenance["interpolated_mm_s"] = [
        list(g) for g in gaps_within(spans, min(got_speeds), max(got_speeds))]
    if lines not in (None, "off"):  # what the fit found, lines or not
        model.provenance["lines"] = {
            "period_mm": line_fit.period_mm, "share": round(line_fit.share, 4),
            "note": line_fit.note}
    if line_fit.spectrum is not None:
        model.lines = line_fit.spectrum.to_json()
    model.two_part, model.free_form = spectral.two_part, spectral.free_form
    model.provenance["spectral_model"] = "free-form"
    model.provenance["two_part_iterations"] = ITERATIONS
    return model, reports


def lines_option(lines: str | float | None, name: str = "lines") -> str | float | None:
    """The ``lines`` option checked: ``"auto"``, ``"off"``/None, or a period in mm (a
    number, or text that is one); a one-line error naming ``name`` otherwise."""
    if lines is None or lines in ("auto", "off"):
        return lines
    try:
        period = float(lines)
    except (TypeError, ValueError):
        raise UserError(f"{name} {lines}: 'auto', 'off' or a period in mm") from None
    if not (math.isfinite(period) and period > 0):
        raise UserError(f"{name} {lines}: the period must be a number of mm > 0")
    return period


def _fit_lines(prepared: list[tuple[Array, Array]], fs: float, speeds_mm_s: Sequence[float],
               tolerance_mm_s: float, lines: str | float | None) -> LineFit:
    """fit_texture's line spectrum: ``"auto"`` finds the period, a number is the period
    in mm, None or ``"off"`` fits none."""
    signals = [x for x, _ in prepared]
    lines = lines_option(lines)
    if lines is None or lines == "off":
        return LineFit.none(signals, "not fitted (lines off)")
    period = None if lines == "auto" else float(lines)
    return fit_lines(signals, [v for _, v in prepared], fs,
                     modelled_speed_range(speeds_mm_s, tolerance_mm_s), period_mm=period)


def modelled_speed_range(speeds_mm_s: Sequence[float], tolerance_mm_s: float
                         ) -> tuple[float, float]:
    """The speeds a fit over ``speeds_mm_s`` reads: each within the tolerance, above 0.5."""
    return max(min(speeds_mm_s) - tolerance_mm_s, 0.5), max(speeds_mm_s) + tolerance_mm_s


@dataclass
class _Spectrum:
    """The calibrated spectrum's all-pole fits at the fitted speeds and its file blocks."""

    hs: list[Array]
    sigma2: list[float]
    two_part: dict
    free_form: dict


def _fit_spectrum(
    whole: list[tuple[Array, Array]], pooled: dict[float, list[Array]],
    speeds_of: dict[float, list[Array]], got_speeds: list[float], fs: float, order: int,
    tolerance_mm_s: float, wrap_iterations: Callable[[Iterable], Iterable],
) -> _Spectrum:
    """The two-part base S_two on every chunk, its calibration at each fitted speed, and
    the all-pole fits of the result; UserError where the scans cannot give it."""
    lo, hi = modelled_speed_range(got_speeds, tolerance_mm_s)
    try:
        two = fit_two_part([w[0] for w in whole], [w[1] for w in whole], fs, (lo, hi),
                           ITERATIONS, wrap=wrap_iterations)
        by = {v: list(zip(pooled[v], speeds_of[v], strict=True)) for v in got_speeds}
        spec = fit_calibrated(by, fs, two)
    except ValueError as exc:
        raise UserError(f"calibrated spectrum: {exc}") from None
    polys = [spec.ar(s, order, fs) for s in got_speeds]
    if not all(is_stable(a) for a, _ in polys):
        raise UserError("spectral model: an all-pole fit of S(f, v) is unstable")
    return _Spectrum([h_from_poly(a) for a, _ in polys], [s2 for _, s2 in polys],
                     two.to_json(), spec.to_json())


#: The plain per-speed fit's grid step: the renderer takes the nearest grid speed, so a
#: speed is never more than half a step from a model fitted around it.
PAPER_GRID_STEP_MM_S = 1.0
#: Where fewer samples lie within the window of a speed, the nearest this many seconds.
PAPER_MIN_SECONDS = 2.0


def fit_paper(
    scans: Iterable[Scan], *, order: int = 200, window_mm_s: float = 5.0,
    highpass_hz: float = 10.0, surface: str | None = None,
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0),
) -> TextureModel:
    """The paper's method read plainly (Fig. 8, eq. 4): for each synthesis speed v, the
    scans high-passed at ``highpass_hz`` and reduced by DFT321, then one LPC of ``order``
    (autocorrelation method) on the samples whose speed is within ``window_mm_s`` of v,
    or the ``PAPER_MIN_SECONDS`` of samples nearest to v in speed where fewer are.

    No coefficients are interpolated: the model holds one such fit every
    ``PAPER_GRID_STEP_MM_S`` over the scanned speeds (1st-99th percentile of the moving
    samples) and the renderer plays the nearest (``interpolation "nearest"``), i.e. a
    per-speed refit to within half a step.
    """
    scans = list(scans)
    if not scans:
        raise UserError("no scans to fit")
    fs = scans[0].fs_hz
    xs, vs = [], []
    for scan in scans:
        if abs(scan.fs_hz - fs) > 1e-6 * fs:
            raise UserError(f"{scan.path}: column 't_s': sample rate {scan.fs_hz:g} Hz differs "
                            f"from the first scan's {fs:g} Hz")
        xs.append(preprocess(scan.acc, fs, highpass_hz))
        vs.append(np.asarray(scan.speed_mm_s, float))
    v_all = np.concatenate(vs)
    moving = v_all[v_all > 1.0]
    step_mm_s, min_seconds = PAPER_GRID_STEP_MM_S, PAPER_MIN_SECONDS
    need = round(min_seconds * fs)
    if moving.size < max(need, 4 * order):
        raise UserError(f"{scans[0].path if len(scans) == 1 else 'scans'}: only "
                        f"{moving.size} moving samples (speed > 1 mm/s) for an order-{order} "
                        f"model (need {max(need, 4 * order)}); record longer or lower --order")
    lo, hi = np.percentile(moving, [1, 99])
    lo = max(step_mm_s * math.floor(lo / step_mm_s), step_mm_s)
    grid = lo + step_mm_s * np.arange(math.floor((hi - lo) / step_mm_s + 1e-9) + 1)
    hs, sig, counts = [], [], []
    for v in grid:
        dist = np.abs(v_all - v)
        limit = window_mm_s
        if np.count_nonzero(dist <= limit) < need:
            limit = float(np.partition(dist, need - 1)[need - 1])
        segs = []
        for x, sv in zip(xs, vs, strict=True):
            segs.extend(x[a:b] for a, b in segment_runs(np.abs(sv - v) <= limit, 1))
        for floor in (1e-9, 1e-7, 1e-5, 1e-3):
            # A positive-definite autocorrelation gives a stable filter; at order 200 over
            # a 60 dB spectrum rounding can break it: a white floor this far down restores it.
            a, s2 = lpc_autocorrelation(segs, order, floor)
            if is_stable(a):
                break
        else:
            raise UserError(f"speed {v:g} mm/s: the fitted filter is unstable")
        hs.append(h_from_poly(a))
        sig.append(s2)
        counts.append(int(sum(s.size for s in segs)))
    model = TextureModel(
        surface=surface or scans[0].surface, fs_hz=fs, speeds_mm_s=grid, h=np.vstack(hs),
        sigma2=np.asarray(sig), highpass_hz=highpass_hz, fit_band_hz=(highpass_hz, fs / 2),
        drive_band_hz=drive_band_hz, tolerance_mm_s=step_mm_s / 2, interpolation="nearest",
        provenance={
            "scans": [s.path for s in scans], "method": "autocorrelation", "order": order,
            "form": "paper", "window_mm_s": window_mm_s, "min_seconds": min_seconds,
            "tool": "fydpad texture fit",
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "samples_per_speed": {f"{v:g}": n for v, n in zip(grid, counts, strict=True)},
        },
    )
    spans = scanned_spans(vs, fs, (float(grid[0]) - window_mm_s, float(grid[-1]) + window_mm_s))
    model.provenance["speed_coverage_mm_s"] = [list(sp) for sp in spans]
    model.provenance["interpolated_mm_s"] = []
    return model
