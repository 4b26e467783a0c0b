"""The LPC texture model file: strict JSON (docs/texture_model_format.md)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from reprlib import repr as _short  # a value for a one-line message: a long list cut
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError, read_json
from fydpad.texture.family import FORMAT, require, save_model_json
from fydpad.texture.lpc.analysis import is_stable, poly_from_h
from fydpad.texture.lpc.coverage import checked_spans

#: Version 2 added a periodic surface's line model (key 'lines'), no longer rendered.
FORMAT_VERSION = 1
#: Interpolations a file may name (:mod:`interpolation` renders each).
INTERPOLATIONS = ("nearest", "stretch")
REFIT = "refit the model with 'fydpad texture fit SCAN.csv ... --out MODEL.json'"
Array = NDArray[np.float64]


@dataclass
class TextureModel:
    """Speed-indexed LPC models of one surface (paper's lookup table of (h, sigma^2))."""

    surface: str
    fs_hz: float
    speeds_mm_s: Array  # (m,) ascending
    h: Array  # (m, p): eq. 4/5 coefficients, a(k) = e(k) + h . [a(k-1) .. a(k-p)]
    sigma2: Array  # (m,) residual variance, (m/s^2)^2
    highpass_hz: float = 10.0
    fit_band_hz: tuple[float, float] = (10.0, 500.0)
    drive_band_hz: tuple[float, float] | None = (165.0, 220.0)
    gain: float = 1.0
    tolerance_mm_s: float = 5.0
    provenance: dict[str, Any] = field(default_factory=dict)
    #: The calibrated form's two-part base and calibration (spectrum.py's to_json()).
    two_part: dict[str, Any] | None = None
    free_form: dict[str, Any] | None = None
    interpolation: str = "nearest"  # between models[]: "nearest" or "stretch" (INTERPOLATIONS)
    #: What ``fydpad texture fit`` validated: the winner and every candidate's figures.
    selection: dict[str, Any] | None = None

    @property
    def order(self) -> int:
        return int(self.h.shape[1])

    def poly(self, i: int) -> Array:
        """A = [1, -h] of model ``i`` (scipy.signal's denominator)."""
        return poly_from_h(self.h[i])


def model_to_json(model: TextureModel) -> dict[str, Any]:
    optional = {"two_part": model.two_part, "free_form": model.free_form,
                "selection": model.selection}
    return {
        "format": FORMAT, "format_version": FORMAT_VERSION,
        "surface": model.surface, "sample_rate_hz": model.fs_hz, "order": model.order,
        "highpass_hz": model.highpass_hz, "fit_band_hz": list(model.fit_band_hz),
        "drive_band_hz": None if model.drive_band_hz is None else list(model.drive_band_hz),
        "gain": model.gain, "speed_tolerance_mm_s": model.tolerance_mm_s,
        "interpolation": model.interpolation,
        "coefficient_convention": "a(k) = e(k) + sum_i h[i] * a(k-1-i), e ~ N(0, sigma2)",
        "units": {"sigma2": "(m/s^2)^2", "speed_mm_s": "mm/s"},
        "models": [
            {"speed_mm_s": float(s), "sigma2": float(v), "h": [float(c) for c in h]}
            for s, v, h in zip(model.speeds_mm_s, model.sigma2, model.h, strict=True)
        ],
        "provenance": model.provenance,
        **{k: v for k, v in optional.items() if v is not None},
    }


def save_model(model: TextureModel, path: str | Path) -> Path:
    """Strict JSON: a non-finite number is a UserError naming the file."""
    return save_model_json(model_to_json(model), path)


def load_model(path: str | Path) -> TextureModel:
    return parse_model(read_json(Path(path), "JSON model"), str(path))


def parse_model(data: Any, where: str = "model") -> TextureModel:
    """Check and convert a parsed JSON model: every value the renderer uses, so a bad
    file fails on reading in one line naming the file and the key."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise UserError(f"{where}: not a fydpad texture model (key 'format' must be '{FORMAT}')")
    version = data.get("format_version")
    if "lines" in data:
        raise UserError(f"{where}: key 'lines' (a periodic surface's line model, format_version "
                        f"2) is a form this fydpad no longer renders; {REFIT}")
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise UserError(f"{where}: key 'format_version' is {version!r}; this fydpad reads "
                        f"version {FORMAT_VERSION} (refit the model with 'fydpad texture fit')")
    fs = _number(data, "sample_rate_hz", where, positive=True)
    hp = _number(data, "highpass_hz", where, 10.0)
    if hp >= fs / 2:
        raise UserError(f"{where}: key 'highpass_hz' {hp:g} Hz must be below the Nyquist "
                        f"frequency {fs / 2:g} Hz of 'sample_rate_hz'")
    provenance = data.get("provenance", {})
    if not isinstance(provenance, dict):
        raise UserError(f"{where}: key 'provenance' must be an object, not {_short(provenance)}")
    for key in ("speed_coverage_mm_s", "interpolated_mm_s"):
        if key in provenance:
            checked_spans(provenance[key], where, key)
    fit_band = _band(data, "fit_band_hz", where, (hp, fs / 2), fs, False)
    drive = data.get("drive_band_hz", (165.0, 220.0))
    drive = None if drive is None else _band(data, "drive_band_hz", where, drive, fs, True)
    gain = _number(data, "gain", where, 1.0)
    tolerance = _number(data, "speed_tolerance_mm_s", where, 5.0)
    interpolation = data.get("interpolation", "stretch")  # absent: the spectral default
    if interpolation not in INTERPOLATIONS:
        raise UserError(f"{where}: key 'interpolation' {_short(interpolation)} is not "
                        f"rendered by this fydpad; {REFIT}")
    _removed_form(data, where)
    models = data.get("models")
    if not isinstance(models, list) or not models:
        raise UserError(f"{where}: key 'models' must be a non-empty list")
    speeds, sig, hs = [], [], []
    for i, m in enumerate(models):
        w = f"{where}: models[{i}]"
        if not isinstance(m, dict):
            raise UserError(f"{w} must be an object, not {_short(m)}")
        speeds.append(_number(m, "speed_mm_s", w, positive=True, unit=" mm/s"))
        sig.append(_number(m, "sigma2", w, positive=True))  # 0: a singular spectrum
        h = _array(m, "h", w, "a non-empty list of finite numbers")
        if hs and h.size != hs[0].size:
            raise UserError(f"{w}: key 'h' has {h.size} coefficients, models[0] has {hs[0].size}")
        if not is_stable(poly_from_h(h)):
            raise UserError(f"{w}: key 'h' is an unstable filter")
        hs.append(h)
    o = data.get("order", hs[0].size)
    if isinstance(o, bool) or not isinstance(o, (int, float)) or o != hs[0].size:
        raise UserError(f"{where}: key 'order' is {_short(o)}, but models[].h have "
                        f"{hs[0].size} coefficients")
    order = np.argsort(speeds)
    if np.any(np.diff(np.asarray(speeds)[order]) <= 0):
        raise UserError(f"{where}: key 'models' has two models at the same speed")
    two, free = data.get("two_part"), data.get("free_form")
    if free is not None:
        _calibrated(two, free, where)
    selection = data.get("selection")
    if selection is not None and not isinstance(selection, dict):
        raise UserError(f"{where}: key 'selection' must be an object, not {_short(selection)}")
    return TextureModel(
        surface=str(data.get("surface", "")), fs_hz=fs, speeds_mm_s=np.asarray(speeds)[order],
        h=np.vstack(hs)[order], sigma2=np.asarray(sig)[order], highpass_hz=hp,
        fit_band_hz=fit_band, drive_band_hz=drive, gain=gain, tolerance_mm_s=tolerance,
        provenance=dict(provenance), interpolation=str(interpolation),
        two_part=None if two is None else dict(two),
        free_form=None if free is None else dict(free), selection=selection,
    )


def _number(d: Any, key: str, where: str, default: float | None = None,
            positive: bool = False, unit: str = "") -> float:
    """``d[key]`` (``default`` when absent; required when None): a finite number >= 0,
    or > 0 where ``positive``, in ``unit`` (named in the message)."""
    v = require(d, key, where, object) if default is None else d.get(key, default)
    if (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            or v < 0 or (positive and v == 0)):
        raise UserError(f"{where}: key '{key}' must be a finite number "
                        f"{'>' if positive else '>='} 0{unit}, not {_short(v)}")
    return float(v)


def _array(d: Any, key: str, where: str, what: str,
           ok: Callable[[Array], Any] = lambda a: a.ndim == 1 and a.size > 0) -> Array:
    """``d[key]``, a list of finite numbers for which ``ok`` holds; else the UserError
    says it must be ``what``."""
    v = require(d, key, where, object)
    try:
        a = np.asarray(v, float) if isinstance(v, list) else None
    except (TypeError, ValueError):  # a ragged list, a string in it
        a = None
    if a is None or not np.isfinite(a).all() or not ok(a):
        raise UserError(f"{where}: key '{key}' must be {what}")
    return a


def _band(data: dict[str, Any], key: str, where: str, default: Any, fs_hz: float,
          open_ends: bool) -> tuple[float, float]:
    """``data[key]`` as [lo, hi] Hz within 0..Nyquist, lo < hi (``open_ends``: 0 < lo and
    hi < Nyquist, as a band-pass filter needs)."""
    v, nyq = data.get(key, default), fs_hz / 2
    if not (isinstance(v, (list, tuple)) and len(v) == 2 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in v) and (0 < v[0] < v[1] < nyq if open_ends else 0 <= v[0] < v[1] <= nyq)):
        rel = "0 < lo < hi <" if open_ends else "0 <= lo < hi <="
        raise UserError(f"{where}: key '{key}' must be [lo, hi] with {rel} {nyq:g} Hz "
                        f"(Nyquist of 'sample_rate_hz'), not {_short(v)}")
    return float(v[0]), float(v[1])


def _removed_form(data: dict[str, Any], where: str) -> None:
    """One line naming a form this fydpad no longer fits or renders, and asking to refit."""
    ff, two, prov = data.get("free_form"), data.get("two_part"), data.get("provenance")
    calibration = ff if isinstance(ff, dict) else {}
    for gone, form in (
        (isinstance(ff, dict) and ff.get("form") != "calibrated",
         f"free_form.form {_short(calibration.get('form'))}"),
        (isinstance(ff, dict) and ff.get("taper_mm_s") is None,
         "free_form.taper_mm_s null (log-linear calibration)"),
        (isinstance(prov, dict) and "speed_normalised" in prov,
         "the speed-normalised form (provenance 'speed_normalised')"),
        (ff is None and two is not None, "the two-part form (key 'two_part' without 'free_form')"),
        (ff is None and data.get("interpolation", "stretch") == "stretch",
         "the pooled form (interpolation 'stretch' without key 'free_form')"),
        (isinstance(two, dict) and "fixed_floor" not in two,
         "a two-part base without 'fixed_floor'"),
    ):
        if gone:
            raise UserError(f"{where}: {form} is a form this fydpad no longer renders; {REFIT}")


#: The two-part base's lists, each with the grid it lies on (its own where it is one).
_TWO_PART_GRIDS = {"f_hz": "f_hz", "k_per_mm": "k_per_mm", "tool": "f_hz",
                   "surface": "k_per_mm", "floor": "f_hz", "v_mm_s": "v_mm_s", "g": "v_mm_s",
                   "n": "v_mm_s", "fixed_floor": "f_hz"}


def _calibrated(two: Any, free: Any, where: str) -> None:
    """The calibrated form's blocks (spectrum.py): the two-part base's lists finite,
    nonnegative and each on its grid; the correction's grids ascending, ``log_c`` one row
    per speed of one value per two-part bin, and a taper > 0."""
    w = f"{where}: free_form"
    if two is None:
        raise UserError(f"{w}: form 'calibrated' needs the key 'two_part', which is missing")
    for key, block in (("two_part", two), ("free_form", free)):
        if not isinstance(block, dict):
            raise UserError(f"{where}: key '{key}' must be an object")
    size: dict[str, int] = {}
    for k, grid in _TWO_PART_GRIDS.items():
        size[k] = _array(two, k, f"{where}: two_part", "a list of at least 2 finite, "
                         "nonnegative numbers", lambda a: a.ndim == 1 and a.size >= 2
                         and (a >= 0).all()).size
        if size[k] != size[grid]:
            raise UserError(f"{where}: two_part.{k} has {size[k]} values, two_part.{grid} "
                            f"{size[grid]}")
    f_hz, v_mm_s = (_array(free, k, w, "an ascending list of finite numbers",
                           lambda a: a.ndim == 1 and a.size > 0 and (np.diff(a) > 0).all())
                    for k in ("f_hz", "v_mm_s"))
    _array(free, "log_c", w, "one row per free_form.v_mm_s of finite values per "
           "free_form.f_hz", lambda a: a.shape == (v_mm_s.size, f_hz.size))
    _number(free, "taper_mm_s", w, positive=True)
    if f_hz.size != size["f_hz"]:
        raise UserError(f"{w}.log_c has {f_hz.size} columns, two_part.f_hz {size['f_hz']}")
