"""The thesis network as a texture family (kind ``"mlp"``): per sample the network, a
first-order DC blocker at the band's 5 Hz edge, gated to 0 without contact or below
``still_mm_s`` (docs/texture_mlp.md, "Rendering"). ``render`` and ``tick`` share their
state; ``audio`` is the same signal for an external actuator.
"""

from __future__ import annotations

import math
from dataclasses import fields
from fractions import Fraction
from typing import Any

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.families.mlp.model import (
    MlpModel,
    delta_force,
    model_to_json,
    parse_mlp,
    velocity_xy,
)
from fydpad.texture.families.mlp.train import TrainConfig, fit_mlp
from fydpad.texture.family import FamilyBase, FingerBlock, Kind, hold_finite, resample_finger

Array = NDArray[np.float64]


class MlpTexture(FamilyBase):
    """A fitted :class:`MlpModel` behind the texture-family contract."""

    kind = "mlp"
    tick_channels = ("vibration",)
    needs = frozenset({"speed_mm_s", "x_mm", "y_mm", "force_change"})

    def __init__(self, model: MlpModel):
        super().__init__()
        self.model, self.surface = model, model.surface
        fs = float(model.fs_hz)
        self.channels = {"vibration": fs, "audio": fs}
        self.still_mm_s = 1.0  # silent below 1 mm/s
        self._alpha = 1.0 - math.exp(-1.0 / (model.df_tau_s * fs))
        self._r = math.exp(-2.0 * math.pi * model.band_hz[0] / fs)  # DC blocker pole
        # Fold input scaling and logsig(z) = 0.5 + 0.5 tanh(z / 2) into the weights:
        # y = c + w2 . tanh(W x + b), four NumPy calls per tick, no temporaries.
        net, s = model.net, model.scaling
        w = 0.5 * net.w_in * s.in_scale
        self._w, self._b = np.ascontiguousarray(w), 0.5 * net.b_in - w @ s.in_offset
        self._w2 = 0.5 * s.out_scale * net.w_out
        self._c = float(s.out_offset + s.out_scale * (net.b_out + 0.5 * net.w_out.sum()))
        self._x, self._z = np.zeros(3), np.zeros(net.b_in.size)
        self.reset()

    def reset(self) -> None:
        """Forget the stroke: direction, force mean, DC blocker."""
        self._last = (math.nan, math.nan, 0.0)
        self._cos, self._sin = 1.0, 0.0
        self._mean: float | None = None
        self._hp_x, self._hp_y = None, 0.0  # the blocker's last in/out (None: none yet)
        self._last_f = 0.0  # the last finite force: a missing reading holds it

    def raw(self, vx: Array, vy: Array, df: Array) -> Array:
        """The network's normal acceleration (m/s^2) for per-sample inputs (eq. 4-7)."""
        z = np.tanh(np.column_stack([vx, vy, df]) @ self._w.T + self._b)
        return self._c + z @ self._w2

    def render(self, finger: FingerBlock, channel: str = "vibration") -> Array:
        self.check_channel(channel)
        fs, n = self.model.fs_hz, finger.t_s.size
        other_rate = abs(finger.fs_hz - fs) > 1e-6 * fs
        if n < (2 if other_rate else 1):
            return np.zeros(n)
        if other_rate:
            # Another rate (the sound card's): rendered at the network's own, where Δf and
            # the blocker are defined, then brought to it by a polyphase filter.
            y = self.render(resample_finger(finger, fs))
            ratio = Fraction(finger.fs_hz / fs).limit_denominator(1000)
            out = ss.resample_poly(y, ratio.numerator, ratio.denominator)
            return np.pad(out[:n], (0, max(0, n - out.size)), mode="edge")
        # Fail safe: a missing speed is 0 (silence), a missing force holds the last one.
        speed = np.where(np.isfinite(finger.speed_mm_s), finger.speed_mm_s, 0.0)
        force = hold_finite(finger.force_n, self._last_f)
        self._last_f = float(force[-1])
        vx, vy, self._last = velocity_xy(finger.x_mm, finger.y_mm, speed, self._last)
        self._cos, self._sin = math.cos(self._last[2]), math.sin(self._last[2])
        df, self._mean = delta_force(force, self.model.fs_hz, self.model.df_tau_s, self._mean)
        r = self.raw(vx, vy, df)
        x_prev = float(r[0]) if self._hp_x is None else self._hp_x
        # y(k) = r(k) - r(k-1) + R y(k-1)
        d = np.diff(np.concatenate([[x_prev], r]))
        y, _ = ss.lfilter([1.0], [1.0, -self._r], d, zi=[self._r * self._hp_y])
        self._hp_x, self._hp_y = float(r[-1]), float(y[-1])
        on = finger.contact & (speed >= self.still_mm_s)
        return np.where(on, y, 0.0)

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float]:
        if not math.isfinite(speed_mm_s):
            speed_mm_s = 0.0
        if math.isfinite(force_n):
            self._last_f = force_n
        else:
            force_n = self._last_f
        lx, ly, th = self._last
        dx, dy = x_mm - lx, y_mm - ly
        if (dx != 0.0 or dy != 0.0) and math.isfinite(dx) and math.isfinite(dy):
            th = math.atan2(dy, dx)
            self._cos, self._sin = math.cos(th), math.sin(th)
        self._last = (x_mm, y_mm, th)
        m = force_n if self._mean is None else self._mean
        df = force_n - m
        self._mean = m + self._alpha * df
        x, z = self._x, self._z
        x[0], x[1], x[2] = speed_mm_s * self._cos, speed_mm_s * self._sin, df
        np.dot(self._w, x, out=z)
        np.add(z, self._b, out=z)
        np.tanh(z, out=z)
        r = self._c + float(np.dot(self._w2, z))
        prev = r if self._hp_x is None else self._hp_x
        y = r - prev + self._r * self._hp_y
        self._hp_x, self._hp_y = r, y
        on = contact and speed_mm_s >= self.still_mm_s
        return (y if on else 0.0,)


def _fit(scans: list, **options: Any) -> dict[str, Any]:
    """``fit_family("mlp", scans, seed=.., learning_rate=.., mode=.., ...)``."""
    if not scans:
        raise UserError("fit --kind mlp: give the scans")
    names = {f.name for f in fields(TrainConfig)}
    surface = options.pop("surface", None)
    bad = sorted(set(options) - names)
    if bad:
        raise UserError(f"mlp fit: unknown option(s) {', '.join(bad)} (known: "
                        f"{', '.join(sorted(names | {'surface'}))})")
    model, _, _ = fit_mlp(scans, TrainConfig(**options), surface=surface)
    return model_to_json(model)


KIND = Kind("mlp", lambda data, where: MlpTexture(parse_mlp(data, where)), _fit,
            fit_options=("surface",))
