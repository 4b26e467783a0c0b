"""Position-indexed friction playback (Jiao 2018, section IV-B): mu(x) = F_f(x) / F_n(x)
(eq. 1) low-passed in position, played back at u = (x - x0) mod L as the electrostatic
``audio`` V = b mu(x) Y(t) (eq. 2) or, on the FYD-pad, as ``tension`` and ``vibration``
(docs/texture_friction.md).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.signal as ss

from fydpad.errors import UserError
from fydpad.texture.family import (
    Array,
    FamilyBase,
    FingerBlock,
    Kind,
    TickPosition,
    optional,
    read_model_json,
    require,
    require_version,
    runs,
    save_model_json,
    section,
)

NAME = "friction"
FORMAT_VERSION = 1
CARRIER_HZ = 240.0  # the most sensitive frequency (Jiao 2018 IV-B)
B_DEFAULT = 400.0  # V per unit mu, before the staircase (Jiao 2018 IV-B)
LOWPASS_HZ = 100.0


def friction_coefficient(friction_n: Array, force_n: Array, min_force_n: float = 0.05
                         ) -> Array:
    """mu = F_f / F_n (Jiao 2018 eq. 1); NaN where the normal force is below ``min_force_n``."""
    fn = np.asarray(force_n, float)
    ff = np.asarray(friction_n, float)
    return np.where(fn >= min_force_n, np.abs(ff) / np.where(fn > 0, fn, 1.0), np.nan)


def lowpass_position(mu: Array, dx_mm: float, cutoff_per_mm: float, order: int = 4) -> Array:
    """Zero-phase Butterworth low-pass of a position-sampled signal (cycles/mm)."""
    if cutoff_per_mm >= 0.5 / dx_mm:
        return np.asarray(mu, float).copy()
    sos = ss.butter(order, cutoff_per_mm, fs=1.0 / dx_mm, output="sos")
    return ss.sosfiltfilt(sos, mu)


def fit_friction(scans: list, *, dx_mm: float = 0.01, lowpass_hz: float = LOWPASS_HZ,
                 min_speed_fraction: float = 0.5, surface: str | None = None,
                 b: float = B_DEFAULT, min_force_n: float = 0.05) -> dict[str, Any]:
    """A friction model file (JSON) from scans with force_n, friction_n and x_mm; only steady
    sliding (speed >= ``min_speed_fraction`` x median: a sticking contact's F_f / F_n is
    anything below mu_s); where scans' strips overlap their mu are averaged."""
    if not (dx_mm > 0 and math.isfinite(dx_mm)):
        raise UserError("--dx-mm must be positive")
    if not scans:
        raise UserError("fit --kind friction: no scans")
    pieces = []
    for sc in scans:
        ff, x = sc.friction_n, sc.x_mm
        if ff is None or sc.force_n is None:
            raise UserError(f"{sc.path}: column 'friction_n' and 'force_n' are needed for a "
                            "friction model (docs/recording_format.md, texture scan)")
        if x is None:
            raise UserError(f"{sc.path}: column 'x_mm' is needed: friction is played back "
                            "by position")
        v = np.abs(sc.speed_mm_s)
        vmed = float(np.median(v[v > 0])) if np.any(v > 0) else 0.0
        mu = friction_coefficient(ff, sc.force_n, min_force_n)
        keep = (v >= min_speed_fraction * vmed) & np.isfinite(x) & np.isfinite(mu)
        if keep.sum() < 16 or vmed <= 0:
            raise UserError(f"{sc.path}: too little steady sliding to fit mu(x)")
        pieces.append((np.asarray(x)[keep], mu[keep], v[keep]))
    v_ref = float(np.median(np.concatenate([p[2] for p in pieces])))
    cutoff = lowpass_hz / v_ref
    x0 = min(float(p[0].min()) for p in pieces)
    n = int((max(float(p[0].max()) for p in pieces) - x0) / dx_mm) + 1
    acc, w = np.zeros(n), np.zeros(n)
    grid = x0 + dx_mm * np.arange(n)
    for x, mu, _ in pieces:
        # Equal positions (a hand that paused): averaged.
        uniq, inv = np.unique(x, return_inverse=True)
        g = np.interp(grid, uniq, np.bincount(inv, mu) / np.bincount(inv),
                      left=np.nan, right=np.nan)
        filt = np.full(n, np.nan)
        # Low-pass each scan's strip on its own (no jump at a strip's edge).
        for a, bnd in runs(np.isfinite(g)):
            seg = g[a:bnd]
            pad = min(seg.size - 1, int(3 / cutoff / dx_mm))
            ext = np.pad(seg, pad, mode="reflect") if pad > 0 else seg
            y = lowpass_position(ext, dx_mm, cutoff)
            filt[a:bnd] = y[pad:pad + seg.size]
        ok = np.isfinite(filt)
        acc[ok] += filt[ok]
        w[ok] += 1.0
    covered, k = w > 0, np.arange(n)
    mu_grid = np.interp(k, k[covered], acc[covered] / w[covered])  # gaps: linear across
    return {
        "format": "fydpad-texture-model", "kind": NAME, "format_version": FORMAT_VERSION,
        "surface": surface or scans[0].surface,
        "x0_mm": x0, "dx_mm": dx_mm, "mu": [round(float(m), 6) for m in mu_grid],
        "lowpass": {"domain": "position", "hz_at_reference_speed": lowpass_hz,
                    "reference_speed_mm_s": v_ref, "cutoff_cycles_per_mm": cutoff},
        "electrostatic": {"b_v": b, "carrier_hz": CARRIER_HZ, "carrier": "square 0/1"},
        "fydpad": {"vibration_gain_m_s2": 2.0, "tension_gain": 1.0, "still_mm_s": 2.0},
        "provenance": {"scans": [str(s.path) for s in scans], "method": "Jiao 2018 IV-B eq. 1"},
    }


class FrictionFamily(FamilyBase):
    """mu(x) played back by position; parameter ``b_v``: the gain b of eq. 2 (V per mu)."""

    kind = NAME
    tick_channels = ("vibration", "tension")
    needs = frozenset({"x_mm", "speed_mm_s"})

    def __init__(self, mu: Array, x0_mm: float, dx_mm: float, *, b: float = B_DEFAULT,
                 carrier_hz: float = CARRIER_HZ, vibration_gain_m_s2: float = 2.0,
                 tension_gain: float = 1.0, still_mm_s: float = 2.0, surface: str = ""):
        super().__init__()
        self.mu = np.asarray(mu, float)
        self._mu = [*self.mu.tolist(), float(self.mu[0])]  # floats for the tick (wraps)
        self.x0_mm, self.dx_mm = float(x0_mm), float(dx_mm)
        self.length_mm, self.mu_mean = self.mu.size * self.dx_mm, float(np.mean(self.mu))
        self.parameters = {"b_v": float(b)}
        self.carrier_hz, self.still_mm_s = float(carrier_hz), float(still_mm_s)
        self.vibration_gain_m_s2 = float(vibration_gain_m_s2)
        self.tension_gain = float(tension_gain)
        self.surface = surface
        self.channels = {"vibration": 1000.0, "tension": 1000.0, "audio": 48e3}
        self._pos = TickPosition()

    @property
    def b(self) -> float:
        return self.parameters["b_v"]

    def set_parameter(self, name: str, value: float) -> None:
        if name == "b_v" and not (isinstance(value, int | float) and math.isfinite(value)):
            raise UserError(f"friction b_v must be a finite number of volts, not {value!r}")
        super().set_parameter(name, float(value))

    def mu_at(self, x_mm: Array | float) -> Array:
        """mu at finger positions (the strip tiled along x: (x - x0) mod L)."""
        u = np.mod(np.asarray(x_mm, float) - self.x0_mm, self.length_mm) / self.dx_mm
        return np.interp(u, np.arange(self.mu.size + 1),
                         np.concatenate([self.mu, self.mu[:1]]))

    def render(self, finger: FingerBlock, channel: str) -> Array:
        self.check_channel(channel)
        c = finger.contact.astype(float)
        mu = self.mu_at(np.where(finger.contact, finger.x_mm, self.x0_mm))
        if channel == "audio":  # Y(t): 1 in the first half of each carrier period (eq. 2)
            carrier = (np.mod(np.asarray(finger.t_s) * self.carrier_hz, 1.0) < 0.5)
            return self.b * mu * carrier.astype(float) * c
        if channel == "tension":
            ten = 1.0 + self.tension_gain * (mu - self.mu_mean) / self.mu_mean
            return np.where(finger.contact, np.clip(ten, 0.5, 1.5), 1.0)
        fade = np.clip(np.asarray(finger.speed_mm_s) / self.still_mm_s, 0.0, 1.0) * c
        return self.vibration_gain_m_s2 * (mu - self.mu_mean) / self.mu_mean * fade

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float, ...]:
        x = self._pos.update(t_s, contact, x_mm)
        if not contact or x != x:
            return (0.0, 1.0)
        u = ((x - self.x0_mm) % self.length_mm) / self.dx_mm
        i = min(int(u), len(self._mu) - 2)
        f = u - i
        mu = self._mu[i] * (1.0 - f) + self._mu[i + 1] * f
        rel = (mu - self.mu_mean) / self.mu_mean
        fade = min(max(speed_mm_s / self.still_mm_s, 0.0), 1.0)
        return (self.vibration_gain_m_s2 * rel * fade,
                min(max(1.0 + self.tension_gain * rel, 0.5), 1.5))

    def reset(self) -> None:
        self._pos.reset()


def parse_friction(data: dict[str, Any], where: str) -> FrictionFamily:
    """Check a friction model file; errors name the file and the key."""
    require_version(data, where, NAME, FORMAT_VERSION)
    try:
        arr = np.asarray(require(data, "mu", where, list), float)
    except (TypeError, ValueError):
        raise UserError(f"{where}: key 'mu' must be a list of numbers") from None
    if arr.ndim != 1 or arr.size < 2 or not np.isfinite(arr).all() or (arr <= 0).any():
        raise UserError(f"{where}: key 'mu' must hold at least 2 finite positive numbers")
    dx = float(require(data, "dx_mm", where))
    if not dx > 0:  # require: finite
        raise UserError(f"{where}: key 'dx_mm' must be positive")
    es, pad = section(data, "electrostatic", where), section(data, "fydpad", where)
    return FrictionFamily(
        arr, float(require(data, "x0_mm", where)), dx,
        b=optional(es, "b_v", f"{where}: electrostatic", B_DEFAULT),
        carrier_hz=optional(es, "carrier_hz", f"{where}: electrostatic", CARRIER_HZ,
                            positive=True),
        vibration_gain_m_s2=optional(pad, "vibration_gain_m_s2", f"{where}: fydpad", 2.0),
        tension_gain=optional(pad, "tension_gain", f"{where}: fydpad", 1.0),
        still_mm_s=optional(pad, "still_mm_s", f"{where}: fydpad", 2.0, positive=True),
        surface=str(data.get("surface", "")))


def describe_fit(data: dict[str, Any], where: str) -> list[str]:
    lp = data["lowpass"]
    return [f"friction mu(x) of {data['surface']}, {len(data['mu'])} points every "
            f"{data['dx_mm']:g} mm from x = {data['x0_mm']:.2f} mm, mean mu "
            f"{np.mean(data['mu']):.3f}; low-pass {lp['cutoff_cycles_per_mm']:.3g} "
            f"cycles/mm (100 Hz at {lp['reference_speed_mm_s']:.1f} mm/s)"]


def set_electrostatic_b(path: str, b_v: float) -> None:
    """Write b (the staircase's result) into a friction model file."""
    data = read_model_json(path)
    parse_friction(data, path)
    data.setdefault("electrostatic", {})["b_v"] = float(b_v)
    save_model_json(data, path)


KIND = Kind(NAME, parse_friction, fit_friction,
            fit_options=("dx_mm", "lowpass_hz", "surface"), describe=describe_fit,
            observable=("tension", (2.0, 100.0), "friction"))  # affine in mu(x), 2-100 Hz
