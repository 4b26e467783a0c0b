"""The texture model file: a documented JSON (docs/texture_model_format.md)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError, read_json
from fydpad.texture.lpc import is_stable, poly_from_h

FORMAT = "fydpad-texture-model"
FORMAT_VERSION = 1
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
    two_part: dict[str, Any] | None = None  # two_part.TwoPartSpectrum.to_json(), if fitted

    @property
    def order(self) -> int:
        return int(self.h.shape[1])

    def poly(self, i: int) -> Array:
        """A = [1, -h] of model ``i`` (scipy.signal's denominator)."""
        return poly_from_h(self.h[i])


def model_to_json(model: TextureModel) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "surface": model.surface,
        "sample_rate_hz": model.fs_hz,
        "order": model.order,
        "highpass_hz": model.highpass_hz,
        "fit_band_hz": list(model.fit_band_hz),
        "drive_band_hz": None if model.drive_band_hz is None else list(model.drive_band_hz),
        "gain": model.gain,
        "speed_tolerance_mm_s": model.tolerance_mm_s,
        "coefficient_convention": "a(k) = e(k) + sum_i h[i] * a(k-1-i), e ~ N(0, sigma2)",
        "units": {"sigma2": "(m/s^2)^2", "speed_mm_s": "mm/s"},
        "models": [
            {"speed_mm_s": float(s), "sigma2": float(v), "h": [float(c) for c in h]}
            for s, v, h in zip(model.speeds_mm_s, model.sigma2, model.h, strict=True)
        ],
        "provenance": model.provenance,
        **({} if model.two_part is None else {"two_part": model.two_part}),
    }


def save_model(model: TextureModel, path: str | Path) -> Path:
    path = Path(path)
    path.write_text(json.dumps(model_to_json(model), indent=1) + "\n", encoding="utf-8")
    return path


def _get(d: dict[str, Any], key: str, where: str) -> Any:
    if key not in d:
        raise UserError(f"{where}: missing key '{key}'")
    return d[key]


def parse_model(data: Any, where: str = "model") -> TextureModel:
    """Check and convert a parsed JSON model; errors name the file and the key."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise UserError(f"{where}: not a fydpad texture model (key 'format' must be '{FORMAT}')")
    version = data.get("format_version")
    if version != FORMAT_VERSION:
        raise UserError(
            f"{where}: key 'format_version' is {version!r}; this fydpad reads version "
            f"{FORMAT_VERSION} only (refit the model with 'fydpad texture fit')"
        )
    fs = float(_get(data, "sample_rate_hz", where))
    models = _get(data, "models", where)
    if not isinstance(models, list) or not models:
        raise UserError(f"{where}: key 'models' must be a non-empty list")
    speeds, sig, hs = [], [], []
    for i, m in enumerate(models):
        w = f"{where}: models[{i}]"
        try:
            speeds.append(float(_get(m, "speed_mm_s", w)))
            sig.append(float(_get(m, "sigma2", w)))
            hs.append(np.asarray(_get(m, "h", w), float))
        except (TypeError, ValueError) as exc:
            raise UserError(f"{w}: {exc}") from None
        if not np.isfinite(hs[-1]).all() or not np.isfinite(sig[-1]) or sig[-1] < 0:
            raise UserError(f"{w}: 'h' or 'sigma2' is not finite and non-negative")
        if hs[-1].size != hs[0].size:
            raise UserError(f"{w}: key 'h' has {hs[-1].size} coefficients, models[0] has "
                            f"{hs[0].size}")
        if not is_stable(poly_from_h(hs[-1])):
            raise UserError(f"{w}: key 'h' is an unstable filter")
    order = np.argsort(speeds)
    if np.any(np.diff(np.asarray(speeds)[order]) <= 0):
        raise UserError(f"{where}: key 'models' has two models at the same speed")
    band = data.get("drive_band_hz", (165.0, 220.0))
    return TextureModel(
        surface=str(data.get("surface", "")),
        fs_hz=fs,
        speeds_mm_s=np.asarray(speeds)[order],
        h=np.vstack(hs)[order],
        sigma2=np.asarray(sig)[order],
        highpass_hz=float(data.get("highpass_hz", 10.0)),
        fit_band_hz=tuple(data.get("fit_band_hz", (10.0, fs / 2))),
        drive_band_hz=None if band is None else (float(band[0]), float(band[1])),
        gain=float(data.get("gain", 1.0)),
        tolerance_mm_s=float(data.get("speed_tolerance_mm_s", 5.0)),
        provenance=dict(data.get("provenance", {})),
        two_part=_two_part(data.get("two_part"), where),
    )


_TWO_PART_KEYS = ("f_hz", "k_per_mm", "tool", "surface", "floor", "v_mm_s", "g", "n")


def _two_part(d: Any, where: str) -> dict[str, Any] | None:
    """Check the optional two-part spectrum: every factor a finite, nonnegative list."""
    if d is None:
        return None
    if not isinstance(d, dict):
        raise UserError(f"{where}: key 'two_part' must be an object")
    for k in _TWO_PART_KEYS:
        try:
            a = np.asarray(_get(d, k, f"{where}: two_part"), float)
        except (TypeError, ValueError) as exc:
            raise UserError(f"{where}: two_part.{k}: {exc}") from None
        if a.ndim != 1 or a.size < 2 or not np.isfinite(a).all() or (a < 0).any():
            raise UserError(f"{where}: two_part.{k} must be a list of at least 2 finite, "
                            "nonnegative numbers")
    for grid, vals in (("f_hz", ("tool", "floor")), ("k_per_mm", ("surface",)),
                       ("v_mm_s", ("g", "n"))):
        for k in vals:
            if len(d[k]) != len(d[grid]):
                raise UserError(f"{where}: two_part.{k} has {len(d[k])} values, "
                                f"two_part.{grid} {len(d[grid])}")
    return dict(d)


def load_model(path: str | Path) -> TextureModel:
    path = Path(path)
    data = read_json(path, "JSON model")
    return parse_model(data, str(path))
