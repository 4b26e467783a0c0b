"""The texture term of eq. (3) in the render process: an LPC texture model rendered at
1 kHz from the finger's speed (paper III-B, Fig. 9)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fydpad.errors import UserError


class TextureSource:
    """Speed from the centroid stream (10 Hz low-pass, evaluated every tick), eq. (5).

    An output limiter guards the motors: switching between very different per-speed
    filters can grow the filter's history even though each filter is stable, so a
    sample beyond ``limit_factor`` times the largest RMS the model produces at its own
    speeds clears the filter (counted in ``resets``) and is clipped.
    """

    def __init__(self, model_path, rate_hz: float = 1000.0, limit_factor: float = 10.0,
                 method: str | None = None, drive_filter: bool = False):
        from fydpad.texture.interpolation import DEFAULT_METHOD
        from fydpad.texture.model_file import TextureModel, load_model
        from fydpad.texture.synthesis import CentroidSpeed, TextureRenderer

        # A path, or an already loaded model (the LPC family of fydpad.texture.families).
        self.model = (model_path if isinstance(model_path, TextureModel)
                      else load_model(model_path))
        check_render_rate(self.model, rate_hz, str(model_path) if not isinstance(
            model_path, TextureModel) else f"texture model '{self.model.surface}'")
        # The interpolation the commands evaluate (`fydpad texture evaluate`) is the one felt.
        self.method = method or DEFAULT_METHOD
        self.renderer = TextureRenderer(self.model, method=self.method,
                                        drive_filter=drive_filter)
        self.speed = CentroidSpeed(cutoff_hz=10.0)
        self.dt_s = 1.0 / rate_hz
        rms = 0.0
        n = int(0.5 * self.model.fs_hz)
        for s in self.model.speeds_mm_s:
            y = self.renderer.block(np.full(n, float(s)), np.ones(n, bool))
            rms = max(rms, float(np.sqrt(np.mean(y[n // 2 :] ** 2))))
        self.renderer.reset()
        self.limit = limit_factor * rms if rms > 0 else math.inf
        self.resets = 0

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float) -> float:
        self.speed.sample(t_s, x_mm, y_mm, contact)
        v = self.renderer.tick(self.speed.tick(self.dt_s), self.speed.contact)
        if not abs(v) <= self.limit:
            self.renderer.reset()
            self.resets += 1
            v = math.copysign(self.limit, v) if math.isfinite(v) else 0.0
        return v


def check_render_rate(model: Any, rate_hz: float, where: str) -> None:
    """An LPC model renders one sample per tick: a model at another ``sample_rate_hz``
    would play at rate_hz / fs_hz times its pitch, so it is refused (naming ``where``)."""
    fs = float(model.fs_hz)
    if not abs(fs - rate_hz) <= 1e-6 * rate_hz:
        raise UserError(f"{where}: key 'sample_rate_hz' is {fs:g} Hz, the station renders at "
                        f"{rate_hz:g} Hz (fit the model on scans at {rate_hz:g} Hz)")


def check_family_rate(family: Any, rate_hz: float, spec: str) -> None:
    """``check_render_rate`` for a family that renders an LPC model (its ``model``); a
    family with its own ``check_rate(rate_hz)`` (a HaTT set: SampleRate a whole multiple
    of the rate) is checked by it. In the main process, before the station starts."""
    from fydpad.texture.model_file import TextureModel

    model = getattr(family, "model", None)
    if isinstance(model, TextureModel):
        check_render_rate(model, rate_hz, spec)
    check = getattr(family, "check_rate", None)
    if callable(check):
        check(rate_hz)


def open_texture(spec: str, rate_hz: float, method: str | None = None,
                 drive_filter: bool = False, lpc_options_only_if_lpc: bool = False):
    """The texture family of ``MODEL.json`` or ``KIND:MODEL.json`` (issue 9), for ``tick``.

    Its ``tick`` returns the values of its ``tick_channels`` ("vibration", "tension").
    ``method`` (an LPC model's interpolation) and ``drive_filter`` (its drive band) apply
    to the families that render an LPC model; another family given them is an error,
    unless ``lpc_options_only_if_lpc`` (the experiment's stimuli, a mix of families).
    """
    from fydpad.texture.families import load_family

    family = load_family(spec)
    check_family_rate(family, rate_hz, spec)
    for name, value in (("method", method), ("drive_filter", drive_filter or None)):
        if value is None:
            continue
        if not hasattr(family, name):
            if lpc_options_only_if_lpc:
                continue
            flag = "--texture-method" if name == "method" else "--drive-filter"
            raise UserError(f"{spec}: {flag} applies to LPC texture models, this one is "
                            f"{family.kind!r}")
        setattr(family, name, value)
    if hasattr(family, "rate_hz"):
        family.rate_hz = rate_hz
    if hasattr(family, "prepare"):  # build everything now, not on the first tick
        family.prepare()
    return family
