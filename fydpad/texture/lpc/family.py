"""The FYD-pad's LPC texture (Bianchi 2015 III-B, eq. 5) behind the family contract: the
model file rendered by :class:`synthesis.TextureRenderer`, ``fydpad texture fit`` through
:mod:`select`. Switching between very different per-speed filters can grow the filter's
history though each filter is stable, so a tick beyond ``LIMIT_FACTOR`` times the model's
largest RMS at its own speeds clears the filter and is clipped
(``counters()["limiter_resets"]``)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.evaluation.evaluate import welch_psd
from fydpad.texture.family import Array, FamilyBase, FingerBlock, Kind, RateMismatch, mixed_surfaces
from fydpad.texture.lpc.analysis import DEFAULT_SPEEDS_MM_S, ar_psd
from fydpad.texture.lpc.coverage import describe, model_gaps, speed_histogram
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import modelled_speed_range
from fydpad.texture.lpc.interpolation import SpeedInterpolator
from fydpad.texture.lpc.model_file import TextureModel, model_to_json, parse_model
from fydpad.texture.lpc.select import fit_candidate, select_model, selection_table
from fydpad.texture.lpc.synthesis import TextureRenderer
from fydpad.texture.plots import SpeedCoverage, plot_spectra
from fydpad.texture.scan_io import Scan

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
        #: drive_filter: band-pass through the model's drive band; seed: the noise's.
        #: Between fitted speeds it renders the model file's ``interpolation``.
        self.parameters = {"drive_filter": False, "seed": None}
        self.limit = math.inf
        self.resets = 0
        self.tick_renderer: TextureRenderer | None = None
        #: ``render``'s renderer: its table is built once (hundreds of all-pole fits for a
        #: calibrated model), then reset and reseeded for each new stroke.
        self._renderer: TextureRenderer | None = None
        self._restart = True

    def set_parameter(self, name: str, value: Any) -> None:
        super().set_parameter(name, value)
        self.tick_renderer = None  # prepare() builds it with the new value
        if name != "seed":
            self._renderer = None
        self._restart = True

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
        r = TextureRenderer(self.model, seed=self.parameters["seed"],
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
        r = self._renderer
        if r is None:
            r = self._renderer = TextureRenderer(
                self.model, drive_filter=self.parameters["drive_filter"], ramp_s=1e-6)
        if self._restart:  # as a new renderer: no history, the noise from the seed
            r.reset()
            r.reseed(self.parameters["seed"])
            r.clamped = False
            r.warmup(float(finger.speed_mm_s[0]) if finger.speed_mm_s.size else 0.0, 0.5)
            self._restart = False
        return r.block(finger.speed_mm_s, finger.contact)

    def reset(self) -> None:
        self._restart = True
        if self.tick_renderer is not None:
            self.tick_renderer.reset()

    def counters(self) -> dict[str, int]:
        return {"limiter_resets": self.resets}

    def covers(self, speed_mm_s: Array) -> NDArray[np.bool_]:
        """Within the fitted speeds widened by the fit's tolerance."""
        v, s, tol = np.asarray(speed_mm_s, float), self.model.speeds_mm_s, self.model.tolerance_mm_s
        return (v >= s[0] - tol) & (v <= s[-1] + tol)

    def unscanned_speeds(self) -> list[tuple[float, float]] | None:
        return model_gaps(self.model.provenance)


def _fit(scans: list, *, form: str = "auto", speeds_mm_s: Sequence[float] = DEFAULT_SPEEDS_MM_S,
         wrap_iterations: Callable[[Iterable], Iterable] = lambda it: it,
         report: Callable[[list[str]], Any] = lambda lines: None, **options: Any
         ) -> dict[str, Any]:
    """The form validation picks on the scans (``form`` "auto", select.py) or the one
    named; ``report`` gets the validation table."""
    if not scans:
        raise UserError("fit: give at least one SCAN.csv")
    if form == "auto":
        model, sel = select_model(scans, speeds_mm_s=speeds_mm_s, wrap=wrap_iterations, **options)
        report(selection_table(sel))
    else:
        model = fit_candidate(form, scans, speeds_mm_s, wrap_iterations=wrap_iterations, **options)
        report([f"  form {form} as asked (--form): not validated"])
    return model_to_json(model)


def check_options(opts: dict[str, Any], fs_hz: float) -> None:
    """The fit's filters and targets against the scans' rate: each option that would
    fail in the fit or be written into the model (failing on reading)."""
    where = f"the scans' Nyquist frequency {fs_hz / 2:g} Hz"
    if opts["order"] < 1:
        raise UserError("--order must be at least 1")
    if len(opts["drive_band_hz"]) != 2:
        raise UserError("--drive-band needs LO,HI")
    hp, (lo, hi) = opts["highpass_hz"], opts["drive_band_hz"]
    if not (math.isfinite(hp) and 0 <= hp < fs_hz / 2):
        raise UserError(f"--highpass-hz {hp:g}: must be >= 0 and below {where}")
    if not (0 < lo < hi < fs_hz / 2):
        raise UserError(f"--drive-band {lo:g},{hi:g}: need 0 < LO < HI < {where}")
    speeds = opts["speeds_mm_s"]
    if not speeds or not all(math.isfinite(v) and v > 0 for v in speeds):
        raise UserError(f"--speeds {','.join(f'{v:g}' for v in speeds)}: every target "
                        "speed must be > 0 mm/s")
    tol = opts["tolerance_mm_s"]
    if not (math.isfinite(tol) and tol >= 0):
        raise UserError(f"--tolerance {tol:g}: must be >= 0 mm/s")


def describe_fit(data: dict[str, Any], where: str) -> list[str]:
    """The model's form and speeds, and the speeds no scan went at."""
    model = parse_model(data, where)
    prov = model.provenance
    head = (f"surface {model.surface}, order {model.order}, {model.fs_hz:g} Hz, form "
            f"{prov['form']}, {len(model.speeds_mm_s)} models at {model.speeds_mm_s[0]:g}-"
            f"{model.speeds_mm_s[-1]:g} mm/s, interpolation {model.interpolation}")
    if "two_part_iterations" in prov:
        head += f", calibrated spectrum on its two-part base ({prov['two_part_iterations']} " \
                "iterations)"
    gaps = model_gaps(prov) or []
    if not gaps:
        return [head]
    middles = ", ".join(f"{round(a + b) / 2:g}" for a, b in gaps)  # to 0.5 mm/s
    return [head, f"  scanned speeds: {describe(prov['speed_coverage_mm_s'])}; no scan "
            f"between {describe(gaps)}: the model interpolates there (less accurately: "
            f"docs/texture.md, 'Speed coverage'); to close the gaps, scan strokes at "
            f"{middles} mm/s"]


def plot_fit(path: str, scans: list[Scan], data: dict[str, Any], opts: dict[str, Any]
             ) -> None:
    """Recorded spectrum at each target speed (its samples within the tolerance) against
    the model rendered there (Bianchi 2015 Fig. 10), and the scans' speed coverage."""
    model = parse_model(data, path)
    interp = SpeedInterpolator(model)
    x = np.concatenate([preprocess(sc.acc, sc.fs_hz, model.highpass_hz) for sc in scans])
    v = np.concatenate([sc.speed_mm_s for sc in scans])
    panels = []
    for s in opts["speeds_mm_s"]:
        try:
            f, pr = welch_psd(x, model.fs_hz, np.abs(v - s) <= opts["tolerance_mm_s"])
        except ValueError:
            continue  # too little near this speed for a spectrum
        a, s2 = interp(float(s))
        panels.append((f"{s:g} mm/s", f, pr, ar_psd(a, s2, f, model.fs_hz)))
    fitted = list(model.speeds_mm_s)
    edges, seconds = speed_histogram([sc.speed_mm_s for sc in scans], model.fs_hz,
                                     modelled_speed_range(fitted, model.tolerance_mm_s))
    plot_spectra(path, panels, f"{model.surface}: recorded vs model "
                 f"({model.provenance['form']}, {model.interpolation})",
                 coverage=SpeedCoverage(edges, seconds, fitted, model_gaps(model.provenance) or []))


def compare_options(scans: list) -> dict[str, Any]:
    """``texture compare``'s quick fit: order 60 at the scans' median speeds to 5 mm/s."""
    return {"order": 60, "speeds_mm_s": sorted({round(float(np.median(s.speed_mm_s)) / 5) * 5.0
                                                for s in scans})}


KIND = Kind("lpc", lambda data, where: LpcFamily(parse_model(data, where), where), _fit,
            set_options=False, check_options=check_options, notes=mixed_surfaces,
            describe=describe_fit, plot=plot_fit, distance="bands", compare_options=compare_options,
            fit_options=("order", "speeds_mm_s", "tolerance_mm_s", "min_seconds",
                         "highpass_hz", "surface", "drive_band_hz", "form",
                         "wrap_iterations", "report"))
