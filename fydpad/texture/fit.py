"""Fitting a speed-indexed LPC texture model from scans (paper Fig. 8)."""

from __future__ import annotations

import datetime as _dt
import math
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.coverage import gaps_within, scanned_spans
from fydpad.texture.dft321 import preprocess
from fydpad.texture.free_form import (
    AUTO,
    DEFAULT_FORM,
    FORMS,
    ONE_SPEED_BASE_ITERATIONS,
    fit_calibrated,
    fit_free_form,
    fit_surface_resolved,
)
from fydpad.texture.lines import LineFit, fit_lines
from fydpad.texture.lpc import h_from_poly, is_stable, lpc_autocorrelation, lpc_burg
from fydpad.texture.model_file import TextureModel
from fydpad.texture.scan_io import Scan
from fydpad.texture.segment import (
    DEFAULT_SPEEDS_MM_S,
    DEFAULT_TOLERANCE_MM_S,
    segment_by_speed,
)
from fydpad.texture.segment import runs as segment_runs
from fydpad.texture.speed_warp import NFFT as _NFFT
from fydpad.texture.speed_warp import (
    ar_from_log_psd,
    fit_exponents,
    log_psd,
    normalised_spectrum,
)
from fydpad.texture.two_part import ITERATIONS, TooLittleData, fit_two_part

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


def fit_speed(
    segments: Sequence[Array], order: int = 200, method: str = "autocorrelation",
    prewhiten_order: int = 8,
) -> tuple[Array, float]:
    """LPC of one speed's preprocessed segments: (A, sigma^2). Raises when unstable.

    Two stages: a low-order LPC P(z) (``prewhiten_order``) flattens the spectral tilt,
    the rest of the order is fitted on the flattened segments, and A = A2 * P. The
    model is still all-pole of ``order`` (eq. 5 unchanged) and stable (a product of
    minimum-phase polynomials). Why: texture spectra span 50-60 dB (a strong low band,
    a sensor-noise floor) and a one-stage order-200 fit then overestimates the floor by
    5-8 dB (the LPC error weights low-level bands lightly); the flattened fit does not.
    """
    q = min(max(prewhiten_order, 0), order - 1)
    segments = [np.asarray(s, float) for s in segments]
    pre = np.array([1.0])
    if q > 0:
        pre, _ = lpc_autocorrelation(segments, q)
        segments = [ss.lfilter(pre, [1.0], s)[q:] for s in segments if s.size > q]
    rest = order - q
    if method == "burg":
        a, s2 = lpc_burg(np.concatenate(segments), rest)
    elif method == "autocorrelation":
        a, s2 = lpc_autocorrelation(segments, rest)
    else:
        raise ValueError(f"unknown LPC method {method!r}")
    a = np.convolve(a, pre)
    if not is_stable(a):
        raise ValueError("the fitted filter is unstable")
    return a, s2


def fit_texture(
    scans: Iterable[Scan], *, order: int = 200, speeds_mm_s: Sequence[float] = DEFAULT_SPEEDS_MM_S,
    tolerance_mm_s: float = DEFAULT_TOLERANCE_MM_S, highpass_hz: float = 10.0,
    min_seconds: float = 0.25, method: str = "autocorrelation", surface: str | None = None,
    prewhiten_order: int = 8, speed_normalise: bool = False, two_part: bool = False,
    free_form: str | None = AUTO, free_form_options: dict | None = None,
    lines: str | float | None = "auto",
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0),
    wrap: Callable[[Iterable], Iterable] = lambda it: it,
    wrap_iterations: Callable[[Iterable], Iterable] = lambda it: it,
) -> tuple[TextureModel, list[FitReport]]:
    """One model per target speed from every run of every scan near that speed.

    Each scan is high-passed at ``highpass_hz`` and reduced by DFT321 as a whole, then
    cut into speed runs; each speed pools the autocorrelations of its runs. ``wrap``
    wraps the scans, ``wrap_iterations`` the spectral models' iterations (progress bars).

    ``speed_normalise``: a second pass fits each speed on its runs resampled to that
    constant speed (:func:`speed_warp.normalised_spectrum`, warp exponents from the
    first pass), so a spatial texture's model is its spectrum *at* that speed, not
    pooled over the +-tolerance a hand wanders; the renderer then interpolates without
    a hold band (the synthesis follows the finger's speed and smears it once, as the
    hand did). Recorded in ``provenance["speed_normalised"]``.

    ``two_part``: fit the two-part spectrum S(f, v) = T(f) U(f/v) g(v) + N(f) n(v) of
    :mod:`two_part` on every 0.5 s chunk of the scans within the modelled speeds (not
    only the segmented runs), store it in the model, and make each speed's (h, sigma^2)
    the all-pole fit of S at that speed; the ``"stretch"`` interpolation then renders
    S at every speed of its table. Takes precedence over ``speed_normalise``.

    ``free_form``: a speed-resolved spectrum of :mod:`free_form`: ``"calibrated"`` (the
    two-part S times a correction measured at each fitted speed on its segmented runs),
    ``"free"`` (S free in f, piecewise linear in v) or ``"surface"`` (the two-part
    surface part freed in speed); ``free_form_options`` go to its fit function. Stored
    in ``model.free_form`` (with the two-part factors it builds on); the ``"stretch"``
    method renders it; each speed's (h, sigma^2) is the all-pole fit of its S.
    ``None``: the pooled per-speed LPC fit alone (the paper's model). The default,
    ``"auto"``: ``"calibrated"`` (it meets the targets on more textures at and between
    the fitted speeds: docs/texture.md) when two or more speeds are fitted, else None;
    None with ``two_part``, ``speed_normalise``
    or a ``method``/``prewhiten_order`` other than the default (options of the per-speed
    fit, which a spectral model's all-pole fits do not use); where the scans are too
    short for it (no 0.5 s chunk within the modelled speeds) the pooled fit, with a
    warning saying why. A form named explicitly is an error on such scans.
    """
    auto = free_form == AUTO
    if auto:
        # The options of the pooled fit's own estimator, or a model of its own, ask for it.
        own = two_part or speed_normalise or method != "autocorrelation" or prewhiten_order != 8
        free_form = None if own else DEFAULT_FORM
    if free_form is not None and free_form not in FORMS:  # before the work, not after
        raise UserError(f"free-form model: form must be one of {FORMS}, not {free_form!r}")
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
    got_speeds, hs, sig, reports = [], [], [], []
    short: list[str] = []  # speeds with data, too little for the order
    for s, segs in pooled.items():
        n = sum(seg.size for seg in segs)
        if n == 0:
            warnings.warn(f"no scan has {min_seconds:g} s within {tolerance_mm_s:g} mm/s of "
                          f"{s:g} mm/s: no model at that speed", stacklevel=2)
            continue
        if n < 4 * order:
            # Another speed may still be fitted: this one is skipped and said (the whole
            # fit fails below only when no speed is left).
            short.append(f"only {n} samples near {s:g} mm/s for an order-{order} model "
                         f"(need at least {4 * order}); record longer or lower --order")
            continue
        try:
            a, s2 = fit_speed(segs, order, method, prewhiten_order)
        except ValueError as exc:
            raise UserError(f"speed {s:g} mm/s: {exc}") from None
        got_speeds.append(s)
        hs.append(h_from_poly(a))
        sig.append(s2)
        sv = float(np.mean(np.concatenate(segs) ** 2))
        reports.append(FitReport(s, n, len(segs), s2, sv, True))
    if not got_speeds and short:
        raise UserError(f"{scans[0].path if len(scans) == 1 else 'scans'}: {short[0]}")
    for msg in short:
        warnings.warn(f"{msg}: no model at that speed", stacklevel=2)
    if not got_speeds:
        raise UserError("no part of the scans is near any target speed (column 'speed_mm_s')")
    label = surface or scans[0].surface
    if auto and len(got_speeds) < 2:
        # Nothing lies between fitted speeds to resolve; within one speed's wander a
        # spectrum following the finger fitted on that little data did worse (one 6 s
        # stroke per surface: sandpaper_p80 identified 1 of 3 times against 3 of 3).
        free_form = None
    spectral = None
    if two_part or free_form:
        try:
            spectral = _fit_spectrum(whole, pooled, speeds_of, got_speeds, fs, order,
                                     tolerance_mm_s, two_part, free_form, free_form_options,
                                     wrap_iterations)
        except ScansTooShort as exc:
            if not auto:
                raise
            warnings.warn(f"no {free_form} spectrum ({exc}): the pooled per-speed fit only; "
                          "record longer strokes for it", stacklevel=2)
    normalised = None
    if spectral is not None:
        hs, sig = spectral.hs, spectral.sigma2
    elif speed_normalise and len(got_speeds) > 1:
        hs, sig, normalised = _speed_normalised(got_speeds, hs, sig, pooled, speeds_of, fs,
                                                highpass_hz, order)
    # A spectral or speed-normalised model replaced each speed's pooled fit: report what
    # the file holds, not the fit it replaced.
    reports = [replace(r, sigma2=float(s2)) for r, s2 in zip(reports, sig, strict=True)]
    model = TextureModel(
        surface=label, fs_hz=fs, speeds_mm_s=np.asarray(got_speeds), h=np.vstack(hs),
        sigma2=np.asarray(sig), highpass_hz=highpass_hz, fit_band_hz=(highpass_hz, fs / 2),
        drive_band_hz=drive_band_hz, tolerance_mm_s=tolerance_mm_s,
        provenance={
            "scans": [s.path for s in scans],
            "method": method, "order": order, "prewhiten_order": prewhiten_order,
            "tool": "fydpad texture fit",
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "samples_per_speed": {f"{r.speed_mm_s:g}": r.n_samples for r in reports},
        },
    )
    if normalised is not None:
        model.provenance["speed_normalised"] = normalised
    # Where the strokes the model was fitted on went, and where it only interpolates
    # (coverage.py): a spectral model reads every chunk within the modelled speeds, the
    # per-speed fits only each speed's runs.
    traces = ([v for _, v in prepared] if spectral is not None
              else [v for s in got_speeds for v in speeds_of[s]])
    spans = scanned_spans(traces, fs, modelled_speed_range(got_speeds, tolerance_mm_s))
    model.provenance["speed_coverage_mm_s"] = [list(sp) for sp in spans]
    model.provenance["interpolated_mm_s"] = [
        list(g) for g in gaps_within(spans, min(got_speeds), max(got_speeds))]
    if lines not in (None, "off"):  # what the fit found, lines or not
        model.provenance["lines"] = {
            "period_mm": line_fit.period_mm, "share": round(line_fit.share, 4),
            "note": line_fit.note}
    if line_fit.spectrum is not None:
        model.lines = line_fit.spectrum.to_json()
    if spectral is not None:
        if spectral.two_part is not None:
            model.two_part = spectral.two_part
            model.provenance["spectral_model"] = "two-part"
            model.provenance["two_part_iterations"] = spectral.iterations
        if spectral.free_form is not None:
            model.free_form = spectral.free_form
            model.provenance["spectral_model"] = "free-form"
        # models[] are the all-pole fits of S at the fitted speeds, not the LPC estimator's.
        model.provenance["method"] = "two-stage all-pole fit of S(f, v)"
        model.provenance["prewhiten_order"] = 8
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


class ScansTooShort(UserError):
    """A spectral model asked for by default cannot be fitted on these scans (no 0.5 s
    chunk within the modelled speeds): the pooled fit stands in for it."""


def _spectrum_error(exc: Exception) -> type[UserError]:
    return ScansTooShort if isinstance(exc, TooLittleData) else UserError


@dataclass
class _Spectrum:
    """A spectral model's all-pole fits at the fitted speeds and its file blocks."""

    hs: list[Array]
    sigma2: list[float]
    two_part: dict | None  # the two-part factors (the calibrated/surface forms' base too)
    free_form: dict | None
    iterations: int | None  # of the two-part fit


def _fit_spectrum(
    whole: list[tuple[Array, Array]], pooled: dict[float, list[Array]],
    speeds_of: dict[float, list[Array]], got_speeds: list[float], fs: float, order: int,
    tolerance_mm_s: float, two_part: bool, free_form: str | None,
    free_form_options: dict | None, wrap_iterations: Callable[[Iterable], Iterable],
) -> _Spectrum:
    """The two-part and/or free-form spectrum of ``fit_texture`` and its all-pole fits;
    ScansTooShort where the scans hold too little for it, UserError on other failures."""
    lo, hi = modelled_speed_range(got_speeds, tolerance_mm_s)
    runs, traces = [w[0] for w in whole], [w[1] for w in whole]
    s_of = spectrum = free = its = None
    if two_part or free_form != "free":
        its = ONE_SPEED_BASE_ITERATIONS if (free_form == "calibrated"
                                            and len(got_speeds) < 2) else ITERATIONS
        try:
            s_of = fit_two_part(runs, traces, fs, (lo, hi), its, wrap=wrap_iterations)
        except ValueError as exc:
            raise _spectrum_error(exc)(f"two-part model: {exc}") from None
        spectrum = s_of.to_json()
    opts = dict(free_form_options or {})
    try:
        if free_form == "calibrated":
            by = {v: list(zip(pooled[v], speeds_of[v], strict=True)) for v in got_speeds}
            s_of = fit_calibrated(by, fs, s_of, **opts)
        elif free_form == "surface":
            s_of = fit_surface_resolved(runs, traces, fs, (lo, hi), s_of,
                                        wrap=wrap_iterations, **opts)
        elif free_form == "free":
            s_of = fit_free_form(runs, traces, fs, (lo, hi), wrap=wrap_iterations, **opts)
    except (ValueError, TypeError) as exc:
        raise _spectrum_error(exc)(f"free-form model ({free_form}): {exc}") from None
    if free_form:
        free = s_of.to_json()
    polys = [s_of.ar(s, order, fs) for s in got_speeds]
    if not all(is_stable(a) for a, _ in polys):
        raise UserError("spectral model: an all-pole fit of S(f, v) is unstable")
    return _Spectrum([h_from_poly(a) for a, _ in polys], [s2 for _, s2 in polys], spectrum,
                     free, its)


def _speed_normalised(speeds: list[float], hs: list[Array], sig: list[float],
                      pooled: dict[float, list[Array]], speeds_of: dict[float, list[Array]],
                      fs: float, highpass_hz: float, order: int
                      ) -> tuple[list[Array], list[float], dict[str, float]]:
    """Refit every speed on its runs moved to that exact speed (see fit_texture)."""
    polys = np.vstack([np.concatenate([[1.0], -h]) for h in hs])
    f_hz = np.arange(_NFFT // 2 + 1) * fs / _NFFT
    beta, gamma = fit_exponents(np.asarray(speeds), log_psd(polys, sig), f_hz,
                                (highpass_hz, fs / 2))
    out_h, out_s = [], []
    for s in speeds:
        acc, n = np.zeros(_NFFT // 2 + 1), 0.0
        for x, v in zip(pooled[s], speeds_of[s], strict=True):
            p, m = normalised_spectrum(x, v, s, beta, gamma)
            acc, n = acc + p, n + m
        a, s2 = ar_from_log_psd(np.log(np.maximum(acc / n, 1e-300)), order)
        if not is_stable(a):
            raise UserError(f"speed {s:g} mm/s: the speed-normalised filter is unstable")
        out_h.append(h_from_poly(a))
        out_s.append(s2)
    return out_h, out_s, {"beta": beta, "gamma": gamma}


#: The plain per-speed fit's grid step: the renderer takes the nearest grid speed, so a
#: speed is never more than half a step from a model fitted around it.
PAPER_GRID_STEP_MM_S = 1.0
#: Where fewer samples lie within the window of a speed, the nearest this many seconds.
PAPER_MIN_SECONDS = 2.0


def fit_paper(
    scans: Iterable[Scan], *, order: int = 200, window_mm_s: float = 5.0,
    highpass_hz: float = 10.0, step_mm_s: float = PAPER_GRID_STEP_MM_S,
    min_seconds: float = PAPER_MIN_SECONDS, surface: str | None = None,
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0),
    speed_range_mm_s: tuple[float, float] | None = None,
) -> TextureModel:
    """The paper's method read plainly (Fig. 8, eq. 4): for each synthesis speed v, the
    scans high-passed at ``highpass_hz`` and reduced by DFT321, then one LPC of ``order``
    (autocorrelation method) on the samples whose speed is within ``window_mm_s`` of v,
    or the ``min_seconds`` of samples nearest to v in speed where fewer are.

    No coefficients are interpolated: the model holds one such fit every ``step_mm_s``
    over the scanned speeds (1st-99th percentile of the moving samples, or
    ``speed_range_mm_s``) and the renderer plays the nearest (``interpolation
    "nearest"``), i.e. a per-speed refit to within half a step.
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
    need = round(min_seconds * fs)
    if moving.size < max(need, 4 * order):
        raise UserError(f"{scans[0].path if len(scans) == 1 else 'scans'}: only "
                        f"{moving.size} moving samples (speed > 1 mm/s) for an order-{order} "
                        f"model (need {max(need, 4 * order)}); record longer or lower --order")
    if speed_range_mm_s is None:
        lo, hi = np.percentile(moving, [1, 99])
    else:
        lo, hi = speed_range_mm_s
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
