"""The FYD-pad's LPC texture (Bianchi 2015 III-B, eq. 5) behind the family contract: an
adapter around :mod:`fydpad.texture.lpc.model_file` (the model) and
:class:`fydpad.texture.lpc.synthesis.TextureRenderer` (the render).

``render`` synthesizes along the block's speed after a 0.5 s warm-up at its first
speed; ``tick`` renders one sample per station tick from the station's speed. An output
limiter guards the motors: switching between very different per-speed filters can grow
the filter's history even though each filter is stable, so a tick beyond
``LIMIT_FACTOR`` times the largest RMS the model produces at its own speeds clears the
filter (counted in ``counters()["limiter_resets"]``) and is clipped.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.evaluate import welch_psd
from fydpad.texture.family import Array, FamilyBase, FingerBlock, Kind, RateMismatch
from fydpad.texture.lpc.analysis import ar_psd, segment_by_speed
from fydpad.texture.lpc.coverage import describe, model_gaps, speed_histogram
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import fit_texture, lines_option, modelled_speed_range
from fydpad.texture.lpc.interpolation import METHODS, SpeedInterpolator
from fydpad.texture.lpc.line_voice import LineVoice
from fydpad.texture.lpc.lines import LineSpectrum
from fydpad.texture.lpc.model_file import TextureModel, model_to_json, parse_model
from fydpad.texture.lpc.select import fit_candidate, select_model, selection_table
from fydpad.texture.lpc.synthesis import TextureRenderer
from fydpad.texture.plots import SpeedCoverage, plot_spectra
from fydpad.texture.scan_io import Scan, read_scan
from vision.recording import RecordingError

#: A tick beyond this many times the model's largest RMS clears the filter.
LIMIT_FACTOR = 10.0


class LpcFamily(FamilyBase):
    """A speed-indexed LPC model (:class:`TextureModel`) as a texture family."""

    kind = "lpc"
    tick_channels = ("vibration",)
    needs = frozenset({"speed_mm_s"})

    def __init__(self, model: TextureModel, path: str | None = None):
        super().__init__()
        self.model = model
        self.path = path or f"texture model '{model.surface}'"
        self.surface = model.surface
        self.channels = {"vibration": float(model.fs_hz)}
        self.highpass_hz = float(model.highpass_hz)
        #: method: interpolation between fitted speeds (the file's own unless set);
        #: drive_filter: band-pass the
        #: output through the model's drive band; seed: the excitation noise's.
        self.parameters = {"method": model.interpolation, "drive_filter": False, "seed": None}
        self.limit = math.inf
        self.resets = 0
        self.tick_renderer: TextureRenderer | None = None
        self._renderer: TextureRenderer | None = None

    def set_parameter(self, name: str, value: Any) -> None:
        if name == "method" and value not in METHODS:
            raise UserError(f"{self.path}: interpolation {value!r} is not one of "
                            f"{', '.join(METHODS)}")
        if name == "method" and value == "stretch" and self.model.free_form is None:
            raise UserError(f"{self.path}: interpolation 'stretch' needs the calibrated "
                            "spectrum (key 'free_form'); this model renders 'nearest'")
        super().set_parameter(name, value)
        self._renderer = self.tick_renderer = None  # rebuilt with the new value

    def check_rate(self, rate_hz: float) -> None:
        """One sample per tick: a model at another rate would play at rate_hz / fs_hz
        times its pitch, so it is refused."""
        fs = float(self.model.fs_hz)
        if not abs(fs - rate_hz) <= 1e-6 * rate_hz:
            raise UserError(f"{self.path}: key 'sample_rate_hz' is {fs:g} Hz, the station "
                            f"renders at {rate_hz:g} Hz (fit the model on scans at "
                            f"{rate_hz:g} Hz)")

    def prepare(self, rate_hz: float) -> None:
        """Builds the tick renderer and measures the limiter's level."""
        self.check_rate(rate_hz)
        fs = float(self.model.fs_hz)
        r = TextureRenderer(self.model, method=self.parameters["method"],
                            drive_filter=self.parameters["drive_filter"])
        rms = 0.0
        n = int(0.5 * fs)
        for s in self.model.speeds_mm_s:
            y = r.block(np.full(n, float(s)), np.ones(n, bool))
            rms = max(rms, float(np.sqrt(np.mean(y[n // 2:] ** 2))))
        r.reset()
        self.limit = LIMIT_FACTOR * rms if rms > 0 else math.inf
        self.tick_renderer = r

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float]:
        r = self.tick_renderer
        if r is None:
            raise RuntimeError(f"{self.path}: prepare(rate_hz) before the first tick")
        v = r.tick(speed_mm_s, contact)
        if not abs(v) <= self.limit:
            r.reset()
            self.resets += 1
            v = math.copysign(self.limit, v) if math.isfinite(v) else 0.0
        return (v,)

    def render(self, finger: FingerBlock, channel: str = "vibration") -> Array:
        self.check_channel(channel)
        if abs(finger.fs_hz - self.model.fs_hz) > 1e-6 * self.model.fs_hz:
            raise RateMismatch(f"key 'sample_rate_hz' {self.model.fs_hz:g} Hz (an LPC model "
                               f"renders at its own rate: fit it on scans at "
                               f"{finger.fs_hz:g} Hz)")
        if self._renderer is None:
            p = self.parameters
            self._renderer = TextureRenderer(self.model, method=p["method"], seed=p["seed"],
                                             drive_filter=p["drive_filter"], ramp_s=1e-6)
            v0 = float(finger.speed_mm_s[0]) if finger.speed_mm_s.size else 0.0
            self._renderer.warmup(v0, 0.5)
        return self._renderer.block(finger.speed_mm_s, finger.contact)

    def reset(self) -> None:
        self._renderer = None
        if self.tick_renderer is not None:
            self.tick_renderer.reset()

    def counters(self) -> dict[str, int]:
        return {"limiter_resets": self.resets}

    def covers(self, speed_mm_s: Array) -> NDArray[np.bool_]:
        """Within the fitted speeds widened by the fit's tolerance."""
        v, s, tol = np.asarray(speed_mm_s, float), self.model.speeds_mm_s, self.model.tolerance_mm_s
        return (v >= s[0] - tol) & (v <= s[-1] + tol)

    def unscanned_speeds(self) -> list[tuple[float, float]] | None:
        return model_gaps(self.model.provenance, self.path)


def _from_json(data: dict[str, Any], where: str) -> LpcFamily:
    return LpcFamily(parse_model(data, where), where)


def _fit(scans: list, **options: Any) -> dict[str, Any]:
    """As ``fydpad texture fit``: the form validated on the scans (select.py)."""
    model, _ = select_model(scans, **options)
    return model_to_json(model)




# ------------------------------------------------------------------ fydpad texture fit
#: The ``fydpad texture fit`` options the LPC fit takes.
FIT_OPTIONS = ("order", "speeds", "tolerance", "min_seconds", "highpass_hz", "surface",
               "drive_band", "lines", "form", "wrap", "wrap_iterations")


def check_fit_options(opts: dict[str, Any], fs_hz: float) -> None:
    """The fit's filters and targets against the scans' rate: each option that would
    fail in the fit or be written into the model (failing on reading)."""
    nyq = fs_hz / 2
    where = f"the scans' Nyquist frequency {nyq:g} Hz"
    if opts["order"] < 1:
        raise UserError("--order must be at least 1")
    if len(opts["drive_band"]) != 2:
        raise UserError("--drive-band needs LO,HI")
    hp = opts["highpass_hz"]
    if not (math.isfinite(hp) and 0 <= hp < nyq):
        raise UserError(f"--highpass-hz {hp:g}: must be >= 0 and below {where}")
    lo, hi = opts["drive_band"]
    if not (0 < lo < hi < nyq):
        raise UserError(f"--drive-band {lo:g},{hi:g}: need 0 < LO < HI < {where}")
    speeds = opts["speeds"]
    if not speeds or not all(math.isfinite(v) and v > 0 for v in speeds):
        raise UserError(f"--speeds {','.join(f'{v:g}' for v in speeds)}: every target "
                        "speed must be > 0 mm/s")
    tol = opts["tolerance"]
    if not (math.isfinite(tol) and tol >= 0):
        raise UserError(f"--tolerance {tol:g}: must be >= 0 mm/s")


def fit_command(scan_paths: list[str], opts: dict[str, Any], out: str,
                plot: str | None) -> tuple[dict[str, Any], list[str], list[str]]:
    """``fydpad texture fit`` (kind lpc): the model, the lines describing it (form,
    lines, speed coverage, each speed's fit), warnings about the scans as a whole, and
    with ``plot`` the recorded against
    the model spectra per speed (Bianchi 2015 Fig. 10)."""
    if not scan_paths:
        raise UserError("fit: give at least one SCAN.csv")
    scans = [read_scan_or_fail(p) for p in scan_paths]
    check_fit_options(opts, scans[0].fs_hz)
    labels = [sc.meta.get("surface") for sc in scans]
    notes = []
    if opts["surface"] is None and None not in labels and len(set(labels)) > 1:
        counts = ", ".join(f"{s} ({labels.count(s)})" for s in dict.fromkeys(labels))
        notes.append(f"the scans are of {len(set(labels))} surfaces (# surface=: {counts}), "
                     f"pooled into one model labelled {labels[0]}; fit each surface on its "
                     "own, or name the mix with --surface")
    if selects(opts):
        data, out_lines = fit_selected(scans, opts, plot)
        return data, out_lines, notes
    wrap = opts.get("wrap", _no_wrap)
    model, reports = fit_texture(
        scans, order=opts["order"], speeds_mm_s=opts["speeds"],
        tolerance_mm_s=opts["tolerance"], highpass_hz=opts["highpass_hz"],
        min_seconds=opts["min_seconds"], surface=opts["surface"],
        drive_band_hz=tuple(opts["drive_band"]), lines=lines_option(opts["lines"], "--lines"),
        wrap=wrap, wrap_iterations=opts.get("wrap_iterations", _no_wrap))
    g2 = 9.80665**2
    out_lines = [f"surface {model.surface}, order {model.order}, {model.fs_hz:g} Hz, "
                 "calibrated spectrum on its two-part base "
                 f"({model.provenance['two_part_iterations']} iterations)"]
    lines = model.provenance.get("lines")
    if lines is not None:
        out_lines.append(f"  lines: {lines['note']}" + (
            "; the LPC models below are fitted on what they leave"
            if model.lines is not None else ""))
    gaps = model_gaps(model.provenance, out) or []
    middles = ", ".join(f"{round(a + b) / 2:g}" for a, b in gaps)  # to 0.5 mm/s
    out_lines.append(
        f"  scanned speeds: {describe(model.provenance['speed_coverage_mm_s'])}"
        + (f"; no scan between {describe(gaps)}: the model interpolates there (less "
           "accurately: docs/texture.md, 'Speed coverage'); to close the gaps, scan "
           f"strokes at {middles} mm/s" if gaps else ""))
    for r in reports:
        out_lines.append(
            f"  {r.speed_mm_s:5.1f} mm/s: {r.n_samples} samples in {r.n_segments} runs, "
            f"sigma2 {r.sigma2:.3g} (m/s^2)^2 = {r.sigma2 / g2:.3g} g^2, "
            f"prediction gain {10 * math.log10(r.signal_var / r.sigma2):.1f} dB, stable")
    if plot:
        plot_fit(plot, model, scans, opts, gaps, out)
    return model_to_json(model), out_lines, notes


def plot_fit(path: str, model: TextureModel, scans: list[Scan], opts: dict[str, Any],
             gaps: list, where: str) -> None:
    """Recorded against model spectra per fitted speed, over the runs the fit used, and
    the scans' speed coverage."""
    lines = None
    if model.lines is not None:  # the lines rendered along the scans' own speeds, once
        voice = LineVoice(LineSpectrum.from_json(model.lines, where), model.fs_hz)
        lines = np.concatenate([voice.block(sc.speed_mm_s) for sc in scans])
    pre = [preprocess(sc.acc, sc.fs_hz, model.highpass_hz) for sc in scans]
    panels = []
    for k, s in enumerate(model.speeds_mm_s):
        segs = []
        for sc, x in zip(scans, pre, strict=True):
            rs = segment_by_speed(sc.speed_mm_s, sc.fs_hz, [s], opts["tolerance"],
                                  opts["min_seconds"])[float(s)]
            mask = np.zeros(x.size, bool)
            for a, b in rs:
                mask[a:b] = True
            segs.append((x, mask))
        x = np.concatenate([a for a, _ in segs])
        m = np.concatenate([b for _, b in segs])
        fr, pr = welch_psd(x, model.fs_hz, m)
        pm = ar_psd(model.poly(k), model.sigma2[k], fr, model.fs_hz)
        if lines is not None:
            pm = pm + welch_psd(lines, model.fs_hz, m)[1]
        panels.append((f"{s:g} mm/s", fr, pr, pm))
    edges, seconds = speed_histogram(
        [sc.speed_mm_s for sc in scans], model.fs_hz,
        modelled_speed_range(list(model.speeds_mm_s), model.tolerance_mm_s))
    plot_spectra(path, panels, f"{model.surface}: recorded vs LPC model"
                 + (" + lines" if lines is not None else ""),
                 coverage=SpeedCoverage(edges, seconds, list(model.speeds_mm_s), gaps))


def selects(opts: dict[str, Any]) -> bool:
    """The validated choice or form paper; form calibrated takes the per-speed fit path
    with its full report."""
    return opts["form"] in ("auto", "paper")


def fit_selected(scans: list[Scan], opts: dict[str, Any], plot: str | None
                 ) -> tuple[dict[str, Any], list[str]]:
    """The form validation picks on the scans (``form`` "auto"), or the one named."""
    kw = dict(order=opts["order"], tolerance_mm_s=opts["tolerance"],
              highpass_hz=opts["highpass_hz"], surface=opts["surface"],
              drive_band_hz=tuple(opts["drive_band"]),
              lines=lines_option(opts["lines"], "--lines"))
    if opts["form"] == "auto":
        model, sel = select_model(scans, speeds_mm_s=opts["speeds"], **kw,
                                  wrap=opts.get("wrap_iterations", _no_wrap))
        table = selection_table(sel)
    else:
        model = fit_candidate(opts["form"], scans, opts["speeds"], **kw)
        table = [f"  form {opts['form']} as asked (--form): not validated"]
    lines = [f"surface {model.surface}, order {model.order}, {model.fs_hz:g} Hz, "
             f"form {model.provenance.get('form', 'calibrated')}, {len(model.speeds_mm_s)} "
             f"models at {model.speeds_mm_s[0]:g}-{model.speeds_mm_s[-1]:g} mm/s, "
             f"interpolation {model.interpolation}"]
    found = model.provenance.get("lines")
    if found is not None:
        lines.append(f"  lines: {found['note']}" + (
            "; the LPC models are fitted on what they leave" if model.lines is not None
            else ""))
    lines += table
    if plot:
        plot_selected(plot, scans, model, opts)
    return model_to_json(model), lines


def plot_selected(path: str, scans: list[Scan], model: TextureModel,
                  opts: dict[str, Any]) -> None:
    """Recorded spectrum at each target speed (its samples within the tolerance) against
    the model rendered there (the all-pole part; a periodic surface's lines apart)."""
    interp = SpeedInterpolator(model)
    x = np.concatenate([preprocess(sc.acc, sc.fs_hz, model.highpass_hz) for sc in scans])
    v = np.concatenate([sc.speed_mm_s for sc in scans])
    panels = []
    for s in opts["speeds"]:
        mask = np.abs(v - s) <= opts["tolerance"]
        try:
            f, pr = welch_psd(x, model.fs_hz, mask)
        except ValueError:
            continue  # too little near this speed for a spectrum
        a, s2 = interp(float(s))
        panels.append((f"{s:g} mm/s", f, pr, ar_psd(a, s2, f, model.fs_hz)))
    plot_spectra(path, panels, f"{model.surface}: recorded vs model "
                 f"({model.provenance.get('form', 'calibrated')}, {model.interpolation})")


def read_scan_or_fail(path: str) -> Scan:
    try:
        return read_scan(path)
    except RecordingError as exc:
        raise UserError(str(exc)) from None


def _no_wrap(it: Iterable) -> Iterable:
    return it


KIND = Kind("lpc", _from_json, _fit,
            "speed-indexed LPC models, eq. 5 of Bianchi 2015 (vibration, 1 kHz)",
            fit_options=FIT_OPTIONS, fit_command=fit_command, distance="bands")
