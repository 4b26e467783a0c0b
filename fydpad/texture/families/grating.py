"""Vibrotactile/friction gratings at a composition ratio (Ito 2019, section 4.2); the levels,
the rectangular profile and the channels as docs/texture_grating.md describes them.

    F_v = A sin(2 pi x / lambda)                       (eq. 1, voice coil, normal)
    V_e = B cos(2 pi x / (2 lambda))                   (eq. 2, electrostatic voltage)
    F_e = mu (W + k V_e^2) = mu (W + k B^2/2 (1 + cos(2 pi x / lambda)))   (eq. 3-4)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fydpad.errors import UserError
from fydpad.texture.family import (
    Array,
    FamilyBase,
    FingerBlock,
    Kind,
    TickPosition,
    optional,
    require,
    require_version,
    section,
)
from fydpad.texture.lpc.dft321 import preprocess

NAME = "grating"
FORMAT_VERSION = 1
PROFILES = ("sine", "rect")
RATIOS = tuple((v, 10 - v) for v in range(11))  # 0:10 ... 10:0


def level_value(level: int, at_1: float, at_10: float) -> float:
    """Linear in force between level 1 and level 10; level 0 is off (Ito 2019 4.2.3)."""
    return 0.0 if level == 0 else at_1 + (level - 1) * (at_10 - at_1) / 9.0


def profile_scalar(x_mm: float, wavelength_mm: float, ridge_fraction: float,
                   edge_mm: float) -> float:
    """:meth:`GratingFamily.p`'s rectangle at one position in floats (the tick: no arrays)."""
    d = ridge_fraction * wavelength_mm
    w = max(min(edge_mm, 0.5 * d, 0.5 * (wavelength_mm - d)), 1e-9)
    ph = (x_mm + w / 2) % wavelength_mm - w / 2

    def step(u: float) -> float:
        return 0.5 - 0.5 * math.cos(math.pi * min(max(u / w + 0.5, 0.0), 1.0))

    return 2.0 * (step(ph) - step(ph - d) - ridge_fraction)


class GratingFamily(FamilyBase):
    """A grating rendered by position at a vibrotactile:friction ratio."""

    kind = NAME
    tick_channels = ("vibration", "tension")
    needs = frozenset({"x_mm"})

    def __init__(self, wavelength_mm: float, *, profile: str = "sine",
                 ridge_fraction: float = 0.9, ratio: tuple[int, int] | None = None,
                 vib_levels_n: tuple[float, float] = (0.05, 0.5),
                 friction_levels_n: tuple[float, float] = (0.02, 0.2),
                 mu: float = 0.5, load_n: float = 0.5, k_n_per_v2: float = 2e-6,
                 vibration_gain_m_s2: float = 2.0, tension_gain: float = 1.0,
                 edge_mm: float = 0.1, surface: str = ""):
        super().__init__()
        if not wavelength_mm > 0:
            raise ValueError("wavelength must be positive")
        if profile not in PROFILES:
            raise ValueError(f"profile must be one of {PROFILES}")
        if not 0 < ridge_fraction < 1:
            raise ValueError(f"ridge fraction must be in (0, 1), got {ridge_fraction:g}")
        self.wavelength_mm = float(wavelength_mm)
        self.profile, self.ridge_fraction, self.edge_mm = profile, ridge_fraction, edge_mm
        default = (8, 2) if wavelength_mm >= 1.0 else (6, 4)  # Ito 2019 Fig. 5
        self.ratio = tuple(ratio) if ratio is not None else default
        if self.ratio not in RATIOS:
            raise ValueError(f"ratio must be v:f with v + f = 10, got {self.ratio}")
        self.vib_levels_n, self.friction_levels_n = vib_levels_n, friction_levels_n
        self.A_n = level_value(self.ratio[0], *vib_levels_n)
        self.Fe_mod_n = level_value(self.ratio[1], *friction_levels_n)  # mu k B^2 / 2
        self.mu, self.load_n, self.k_n_per_v2 = mu, load_n, k_n_per_v2
        self.B_v = math.sqrt(2 * self.Fe_mod_n / (mu * k_n_per_v2))
        self.vibration_gain_m_s2, self.tension_gain = vibration_gain_m_s2, tension_gain
        self.surface = surface
        self.channels = {"vibration": 1000.0, "tension": 1000.0, "audio": 48e3, "force": 48e3}
        self._pos = TickPosition()

    def p(self, x_mm: Array) -> Array:
        """p(x): sin(2 pi x / lambda), or the zero-mean rectangular 2 (r(x) - d)."""
        lam, rf, x = self.wavelength_mm, self.ridge_fraction, np.asarray(x_mm, float)
        if self.profile == "sine":
            return np.sin(2 * np.pi * x / lam)
        d = rf * lam
        w = max(min(self.edge_mm, 0.5 * d, 0.5 * (lam - d)), 1e-9)
        # In [-w/2, lambda - w/2): the rise edge centred at 0, the fall at d, each w wide.
        ph = np.mod(x + w / 2, lam) - w / 2

        def step(u: Array) -> Array:
            return 0.5 - 0.5 * np.cos(np.pi * np.clip(u / w + 0.5, 0.0, 1.0))

        return 2.0 * (step(ph) - step(ph - d) - rf)

    def voltage(self, x_mm: Array) -> Array:
        """V_e (eq. 2), V; for the rectangle the non-negative root of V_e^2."""
        x = np.asarray(x_mm, float)
        if self.profile == "sine":
            return self.B_v * np.cos(2 * np.pi * x / (2 * self.wavelength_mm))
        return np.sqrt(np.maximum(self.voltage_sq(x), 0.0))

    def voltage_sq(self, x_mm: Array) -> Array:
        """V_e^2 (eq. 2): B^2 cos^2(pi x / lambda) = B^2 (1 + p(x + lambda/4)) / 2."""
        if self.profile == "sine":
            return self.voltage(x_mm) ** 2
        return self.B_v ** 2 * 0.5 * (1.0 + self.p(np.asarray(x_mm) + self.wavelength_mm / 4))

    def force_e(self, x_mm: Array) -> Array:
        """F_e = mu (W + k V_e^2) (eq. 3), N."""
        return self.mu * (self.load_n + self.k_n_per_v2 * self.voltage_sq(x_mm))

    def render(self, finger: FingerBlock, channel: str) -> Array:
        self.check_channel(channel)
        c = finger.contact
        x = np.where(c, finger.x_mm, 0.0)
        if channel == "vibration":  # F_v = A p(x) (eq. 1), over A_10
            return self.vibration_gain_m_s2 * (self.A_n * self.p(x)) / self.vib_levels_n[1] * c
        if channel == "force":
            return self.A_n * self.p(x) * c
        if channel == "audio":
            return self.voltage(x) * c
        mean = self.mu * self.load_n + self.Fe_mod_n
        ten = 1.0 + self.tension_gain * (self.force_e(x) - mean) / (self.mu * self.load_n)
        return np.where(c, np.clip(ten, 0.5, 1.5), 1.0)

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float, ...]:
        x = self._pos.update(t_s, contact, x_mm)
        if not contact or x != x:
            return (0.0, 1.0)
        lam = self.wavelength_mm
        if self.profile == "sine":  # scalar math: no array per tick
            fv = self.A_n * math.sin(2 * math.pi * x / lam)
            v2 = (self.B_v * math.cos(math.pi * x / lam)) ** 2
        else:
            rf, e = self.ridge_fraction, self.edge_mm
            fv = self.A_n * profile_scalar(x, lam, rf, e)
            v2 = self.B_v ** 2 * 0.5 * (1.0 + profile_scalar(x + lam / 4, lam, rf, e))
        fe = self.mu * (self.load_n + self.k_n_per_v2 * v2)
        mean = self.mu * self.load_n + self.Fe_mod_n
        ten = 1.0 + self.tension_gain * (fe - mean) / (self.mu * self.load_n)
        return (self.vibration_gain_m_s2 * fv / self.vib_levels_n[1], min(max(ten, 0.5), 1.5))

    def reset(self) -> None:
        self._pos.reset()


def estimate_wavelength(scans: list, band_mm: tuple[float, float] = (0.3, 10.0),
                        dx_mm: float = 0.02, fmax_per_mm: float = 5.0) -> float:
    """A grating's period from the scans' spatial power spectrum (docs/texture_grating.md,
    "Fit"): the period whose lines k / lambda < ``fmax_per_mm`` stand highest in sum."""
    logs = []
    for sc in scans:
        x = np.cumsum(sc.speed_mm_s) / sc.fs_hz if sc.x_mm is None else sc.x_mm
        a = preprocess(sc.acc, sc.fs_hz, 10.0)
        keep = sc.speed_mm_s > 0.5 * np.median(sc.speed_mm_s)
        xs, idx = np.unique(x[keep], return_index=True)  # the first sample at each x
        grid = np.arange(xs[0], xs[-1], dx_mm)
        g = np.interp(grid, xs, a[keep][idx])
        f = np.fft.rfftfreq(g.size, dx_mm)
        p = np.abs(np.fft.rfft((g - g.mean()) * np.hanning(g.size))) ** 2
        logs.append((f, p))
    f, p = logs[0][0], np.mean([np.interp(logs[0][0], fi, pi) for fi, pi in logs], axis=0)
    lp = np.log(p + 1e-30 * p.max())
    # Each bin's largest neighbour (a line spreads over a bin or two), over its median.
    lp = np.maximum(np.maximum(lp, np.roll(lp, 1)), np.roll(lp, -1))
    lp -= np.median(lp[(f > 1 / band_mm[1]) & (f < fmax_per_mm)])
    df = f[1] - f[0]

    def lines(lam: float, skip: int = 0, mean: bool = False) -> float:
        """Log-power over the median summed (or averaged) at the lines k / lam < fmax;
        ``skip``: only the lines with k not a multiple of it."""
        k = np.arange(1, int(fmax_per_mm * lam) + 1)
        if skip:
            k = k[k % skip != 0]
        if k.size == 0:
            return -np.inf
        v = lp[np.clip(np.round(k / lam / df).astype(int), 1, f.size - 2)]
        return float(np.mean(v) if mean else np.sum(v))

    cand = np.geomspace(band_mm[0], band_mm[1], 3000)
    best = float(cand[int(np.argmax([lines(lam) for lam in cand]))])
    # A multiple of the period scores as well as the period (its extra lines add ~0):
    # go down to best / m while the lines best / m lacks do not stand 10 dB out.
    while True:
        for m in (2, 3, 4, 5):
            if best / m >= band_mm[0] and lines(best, skip=m, mean=True) < math.log(10.0):
                best /= m
                break
        else:
            return best


def fit_grating(scans: list | None = None, *, wavelength_mm: float | None = None,
                profile: str = "rect", ridge_fraction: float = 0.9,
                ratio: tuple[int, int] | None = None, surface: str | None = None
                ) -> dict[str, Any]:
    """A grating model file (JSON dict): parametric, lambda given or estimated from scans."""
    how = "given"
    if wavelength_mm is not None and not (wavelength_mm > 0 and math.isfinite(wavelength_mm)):
        raise UserError("--wavelength-mm must be positive")
    if wavelength_mm is None:
        if not scans:
            raise UserError("fit --kind grating: give --wavelength-mm or scans to estimate it")
        wavelength_mm = estimate_wavelength(scans)
        how = "estimated from the scans' spatial spectrum"
    try:
        fam = GratingFamily(wavelength_mm, profile=profile, ridge_fraction=ridge_fraction,
                            ratio=ratio)
    except (TypeError, ValueError) as exc:  # --set profile=..., ridge_fraction=..., ratio=...
        raise UserError(f"fit --kind grating: {exc}") from None
    return {
        "format": "fydpad-texture-model", "kind": NAME, "format_version": FORMAT_VERSION,
        "surface": surface or (scans[0].surface if scans else f"grating_{wavelength_mm:g}mm"),
        "wavelength_mm": float(wavelength_mm), "profile": profile,
        "ridge_fraction": ridge_fraction, "ratio": list(fam.ratio),
        "levels": {"vibrotactile_n": list(fam.vib_levels_n),
                   "friction_n": list(fam.friction_levels_n)},
        "electrostatic": {"mu": fam.mu, "load_n": fam.load_n, "k_n_per_v2": fam.k_n_per_v2},
        "fydpad": {"vibration_gain_m_s2": fam.vibration_gain_m_s2,
                   "tension_gain": fam.tension_gain},
        "provenance": {"wavelength": how,
                       "scans": [str(s.path) for s in scans] if scans else []},
    }


def _pair(d: dict, key: str, where: str) -> tuple[float, float]:
    v = require(d, key, where, list)
    if len(v) != 2 or not all(isinstance(a, int | float) and not isinstance(a, bool)
                              and 0 <= a < math.inf for a in v) or not v[1] > 0:
        raise UserError(f"{where}: key '{key}' must be [level_1, level_10], non-negative, "
                        "level 10 positive (the levels are relative to it)")
    return float(v[0]), float(v[1])


def parse_grating(data: dict[str, Any], where: str) -> GratingFamily:
    """Check a grating model file; errors name the file and the key."""
    require_version(data, where, NAME, FORMAT_VERSION)
    lam = float(require(data, "wavelength_mm", where))
    if not lam > 0:  # require: finite
        raise UserError(f"{where}: key 'wavelength_mm' must be positive")
    profile = require(data, "profile", where, str)
    if profile not in PROFILES:
        raise UserError(f"{where}: key 'profile' must be one of {', '.join(PROFILES)}")
    ratio = require(data, "ratio", where, list)
    if tuple(ratio) not in RATIOS:
        raise UserError(f"{where}: key 'ratio' must be [v, f] with v + f = 10, got {ratio}")
    levels = require(data, "levels", where, dict)
    es, pad = section(data, "electrostatic", where), section(data, "fydpad", where)
    rf = optional(data, "ridge_fraction", where, 0.9)
    if not 0 < rf < 1:
        raise UserError(f"{where}: key 'ridge_fraction' must be in (0, 1)")
    return GratingFamily(
        lam, profile=profile, ridge_fraction=rf, ratio=tuple(ratio),
        vib_levels_n=_pair(levels, "vibrotactile_n", f"{where}: levels"),
        friction_levels_n=_pair(levels, "friction_n", f"{where}: levels"),
        mu=optional(es, "mu", f"{where}: electrostatic", 0.5, positive=True),
        load_n=optional(es, "load_n", f"{where}: electrostatic", 0.5, positive=True),
        k_n_per_v2=optional(es, "k_n_per_v2", f"{where}: electrostatic", 2e-6, positive=True),
        vibration_gain_m_s2=optional(pad, "vibration_gain_m_s2", f"{where}: fydpad", 2.0),
        tension_gain=optional(pad, "tension_gain", f"{where}: fydpad", 1.0),
        surface=str(data.get("surface", "")))


def describe_fit(data: dict[str, Any], where: str) -> list[str]:
    return [f"grating {data['profile']} lambda {data['wavelength_mm']:.3f} mm "
            f"({data['provenance']['wavelength']}), ratio {data['ratio'][0]}:{data['ratio'][1]}"]


KIND = Kind(NAME, parse_grating, fit_grating,
            fit_options=("wavelength_mm", "profile", "ratio", "surface"),
            describe=describe_fit)
