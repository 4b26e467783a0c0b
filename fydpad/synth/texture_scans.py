"""Synthetic texture scans from a physical picture, not an AR process.

A hand drags a tool (tip + accelerometer) over a surface. Per stroke:

- the hand's speed wanders around the target like a hand's (ramps at both ends, a
  slow sway and a random drift), so the stroke is only partly within 5 mm/s;
- the tip follows the surface profile h(x) (gratings, ribs, random roughness, pits),
  smoothed by the tip's contact patch; its vertical acceleration is d^2 h(x(t))/dt^2;
- the tip is held on the surface by a preload that follows the hand's normal load;
  where the profile falls faster than the preload can pull it down, the tip leaves,
  flies over what it passes (a ballistic path) and lands with an impact
  (:func:`tip_path`): a non-linearity no linear model holds. At the textures' own
  loads only brick (from 30 mm/s, rarely) and sandpaper_p320 (at 40) meet it; a light
  hand (``load_scale=0.3``) meets it on brick and the sandpapers from 20-30 mm/s, more
  the faster, and on cork barely (docs/texture.md, "The scan generator");
- friction stick-slip: the tip sticks, the tangential force builds and releases at
  random slip distances, each release an impulse along the stroke;
- the tool resonates (a second-order mode whose frequency depends on the contact
  stiffness of the surface), and the accelerometer adds white noise;
- the hand's slow motion and gravity (with a slowly tilting hand) appear on all axes.

With ``friction=True`` the scan also carries ``force_n`` and ``friction_n``
from a separate physical model (:func:`friction_forces`; the acceleration columns are the
same with or without it): the hand's varying normal load (the one the preload follows),
Coulomb friction on the local slope of the same profile h(x) with a material coefficient
that varies along x, and stick-slip of the contact through the tool's tangential
stiffness.

Simulated at 10 kHz, decimated (anti-aliased) to the output rate. Deterministic per
seed: the surface depends on the texture (its random draws seeded by its name), the
stroke on ``seed``.
The paper's specimens R1 and R2 are rectangular gratings of period 3.90 mm and
2.15 mm with a ridge 90 % of the period: every tenth harmonic of speed/period
vanishes.
"""

from __future__ import annotations

import functools
import math
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.synth.hatt import PennRenderer
from fydpad.texture.families.penn.toolkit import PennModelSet
from fydpad.texture.scan_io import Scan, write_scan
from vision.recording import CsvRowWriter

Array = NDArray[np.float64]
SIM_FS_HZ = 10_000.0
DX_MM = 0.004
SURFACE_MM = 2400.0
G = 9.81


@dataclass(frozen=True)
class Texture:
    """Parameters of one synthetic surface (lengths in mm, accelerations in m/s^2)."""

    name: str
    period_mm: float = 0.0  # periodic relief (0: none)
    ridge_fraction: float = 0.9  # rectangular grating; 0 means sinusoidal ribs
    period_jitter: float = 0.0  # relative jitter of each period (wood grain)
    relief_mm: float = 0.0
    rough_mm: float = 0.0  # random roughness RMS
    rough_band_mm: tuple[float, float] = (0.05, 1.0)  # wavelengths
    pits_per_mm: float = 0.0
    pit_mm: float = 0.0  # pit depth
    tip_mm: float = 0.03  # contact patch (Gaussian sigma) smoothing the profile
    resonance_hz: float = 200.0
    damping: float = 0.08
    # The largest downward acceleration the contact can follow at the hand's mean load
    # (the load over the tool's mass, gravity included).
    preload_m_s2: float = 40.0
    slip_mm: float = 0.0  # mean stick-slip distance (0: none)
    slip_m_s2: float = 0.0  # impulse strength per slip


TEXTURES: dict[str, Texture] = {t.name: t for t in (
    # The paper's silicone specimens (SS1/SS3: R1, SS2/SS4: R2): soft, a large patch.
    Texture("R1", period_mm=3.90, ridge_fraction=0.9, relief_mm=0.02, tip_mm=0.06,
            resonance_hz=160.0, damping=0.12, preload_m_s2=1e9, slip_mm=0.4, slip_m_s2=0.4),
    Texture("R2", period_mm=2.15, ridge_fraction=0.9, relief_mm=0.02, tip_mm=0.06,
            resonance_hz=160.0, damping=0.12, preload_m_s2=1e9, slip_mm=0.4, slip_m_s2=0.4),
    Texture("sandpaper_p80", rough_mm=0.006, rough_band_mm=(0.08, 1.5), tip_mm=0.02,
            resonance_hz=310.0, damping=0.06, preload_m_s2=60.0),
    Texture("sandpaper_p320", rough_mm=0.0008, rough_band_mm=(0.03, 0.3), tip_mm=0.01,
            resonance_hz=290.0, damping=0.05, preload_m_s2=25.0),
    Texture("wood_grain", period_mm=0.8, ridge_fraction=0.0, period_jitter=0.2,
            relief_mm=0.006, rough_mm=0.001, rough_band_mm=(0.05, 0.5), resonance_hz=240.0,
            damping=0.07),
    Texture("canvas", period_mm=1.2, ridge_fraction=0.5, relief_mm=0.01, tip_mm=0.08,
            resonance_hz=200.0, damping=0.1, slip_mm=0.15, slip_m_s2=0.3),
    Texture("felt", rough_mm=0.02, rough_band_mm=(0.2, 3.0), tip_mm=0.1,
            resonance_hz=90.0, damping=0.25),
    Texture("glass", rough_mm=0.0002, rough_band_mm=(0.02, 0.2), resonance_hz=330.0,
            damping=0.04, slip_mm=0.05, slip_m_s2=0.8),
    Texture("cork", pits_per_mm=0.6, pit_mm=0.03, rough_mm=0.002, rough_band_mm=(0.1, 1.0),
            tip_mm=0.05, resonance_hz=150.0, damping=0.12),
    Texture("brick", rough_mm=0.03, rough_band_mm=(0.1, 3.0), pits_per_mm=0.3, pit_mm=0.08,
            tip_mm=0.04, resonance_hz=260.0, damping=0.06, preload_m_s2=40.0),
    Texture("mesh_steel", period_mm=0.6, ridge_fraction=0.5, relief_mm=0.004, tip_mm=0.03,
            resonance_hz=350.0, damping=0.04),
    Texture("corduroy", period_mm=2.5, ridge_fraction=0.0, relief_mm=0.15, tip_mm=0.05,
            rough_mm=0.001, resonance_hz=120.0, damping=0.15),
    Texture("rubber", rough_mm=0.001, rough_band_mm=(0.05, 0.5), resonance_hz=110.0,
            damping=0.1, slip_mm=0.3, slip_m_s2=1.5),
    Texture("aluminum_knurl", period_mm=1.0, ridge_fraction=0.6, relief_mm=0.008,
            tip_mm=0.025, resonance_hz=380.0, damping=0.03, preload_m_s2=30.0),
)}
PAPER_SPECIMENS = ("R1", "R2")


def _surface_rng(texture: Texture) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(texture.name.encode()))


def surface_profile(texture: Texture) -> Array:
    """h(x) in mm on a grid of DX_MM over SURFACE_MM, tip smoothing applied."""
    rng = _surface_rng(texture)
    n = int(SURFACE_MM / DX_MM)
    x = np.arange(n) * DX_MM
    h = np.zeros(n)
    if texture.period_mm > 0 and texture.relief_mm > 0:
        if texture.period_jitter > 0:  # each period stretched a little: grain
            periods = texture.period_mm * (1 + texture.period_jitter * rng.uniform(
                -1, 1, int(SURFACE_MM / texture.period_mm) + 10))
            edges = np.concatenate([[0.0], np.cumsum(periods)])
            k = np.searchsorted(edges, x, side="right") - 1
            phase = (x - edges[k]) / periods[np.minimum(k, periods.size - 1)]
        else:
            phase = (x / texture.period_mm) % 1.0
        if texture.ridge_fraction > 0:  # rectangular: ridge then groove
            h += np.where(phase < texture.ridge_fraction, 0.0, -texture.relief_mm)
        else:
            h += 0.5 * texture.relief_mm * np.cos(2 * np.pi * phase)
    if texture.rough_mm > 0:
        spec = np.fft.rfft(rng.standard_normal(n))
        k = np.fft.rfftfreq(n, DX_MM)  # cycles per mm
        lo, hi = 1.0 / texture.rough_band_mm[1], 1.0 / texture.rough_band_mm[0]
        shape = np.where((k >= lo) & (k <= hi), 1.0 / np.maximum(k, lo) ** 0.5, 0.0)
        r = np.fft.irfft(spec * shape, n)
        h += texture.rough_mm * r / (np.std(r) + 1e-30)
    if texture.pits_per_mm > 0:
        npits = rng.poisson(texture.pits_per_mm * SURFACE_MM)
        centres = rng.uniform(0, SURFACE_MM, npits)
        widths = rng.uniform(0.1, 0.4, npits)
        depth = texture.pit_mm * rng.uniform(0.5, 1.5, npits)
        idx = (centres / DX_MM).astype(int)
        for c, w, d in zip(idx, widths, depth, strict=True):
            half = int(w / DX_MM / 2)
            a, b = max(0, c - half), min(n, c + half)
            h[a:b] -= d  # flat-bottomed pits: sharp edges
    if texture.tip_mm > 0:  # a linear smoothing: keeps the grating's spectral zeros
        half = int(4 * texture.tip_mm / DX_MM)
        ker = np.exp(-0.5 * ((np.arange(-half, half + 1) * DX_MM) / texture.tip_mm) ** 2)
        h = ss.fftconvolve(h, ker / ker.sum(), mode="same")
    return h


# Keyed by the whole (frozen) texture: a variant that keeps a name but changes a field
# (dataclasses.replace(TEXTURES["glass"], slip_mm=0)) has a profile of its own. Bounded:
# a profile is 4.8 MB, and a study may sweep many variants.
@functools.lru_cache(maxsize=32)
def _profile(texture: Texture) -> Array:
    return surface_profile(texture)


def hand_speed(speed_mm_s: float, seconds: float, fs: float, rng: np.random.Generator,
               variation: float = 1.0) -> Array:
    """A hand's speed around a target: ramps, a sway (0.3-0.8 Hz) and a random drift."""
    n = round(seconds * fs)
    t = np.arange(n) / fs
    sway = 0.1 * np.sin(2 * np.pi * rng.uniform(0.3, 0.8) * t + rng.uniform(0, 2 * np.pi))
    drift = 0.06 * slow_noise(n, fs, 0.7, rng, pad_s=2.0)
    v = speed_mm_s * (1.0 + variation * (sway + drift))
    ramp = min(0.3, seconds / 4) * (variation > 0)
    if ramp > 0:
        env = np.clip(np.minimum(t, seconds - t) / ramp, 0, 1)
        v *= 0.5 - 0.5 * np.cos(np.pi * env)
    return np.maximum(v, 0.0)


def hand_load(n: int, fs: float, rng: np.random.Generator) -> Array:
    """The hand's normal load over its mean: a 0.5-1.5 Hz sway of 15 % and a drift
    below 1.5 Hz of 10 % RMS (``n`` samples at ``fs``)."""
    t = np.arange(n) / fs
    drift = slow_noise(n, fs, 1.5, rng, pad_s=1.0)
    return (1.0 + 0.15 * np.sin(2 * np.pi * rng.uniform(0.5, 1.5) * t
                                + rng.uniform(0, 2 * np.pi))
            + 0.1 * drift)


def slow_noise(n: int, fs: float, cutoff_hz: float, rng: np.random.Generator,
               pad_s: float) -> Array:
    """Unit-RMS Gaussian noise low-passed at ``cutoff_hz`` (2nd-order Butterworth, forward
    and backward), stationary from its first sample to its last.

    Filtered from rest over ``pad_s`` of noise either side, then cut off: sosfiltfilt
    starts each pass at the steady state of its edge sample instead, at 10 kHz a
    transient of tens of times the drift's RMS that lasts a second and, normalised away,
    leaves the middle a fraction of its RMS (a hand's speed drift of 6 % was 0.7-2.6 %
    mid-stroke, up to 60 % off in its first and last 0.3 s; the load went negative)."""
    pad = round(pad_s * fs)
    sos = ss.butter(2, cutoff_hz, fs=fs, output="sos")
    noise = rng.standard_normal(n + 2 * pad)
    drift = ss.sosfilt(sos, ss.sosfilt(sos, noise)[::-1])[::-1][pad:pad + n]
    return drift / (np.std(drift) + 1e-12)


def tip_path(surface_m: Array, preload_m_s2: Array, fs: float) -> Array:
    """The tip's height (m) over a surface it is pressed onto with ``preload_m_s2``.

    In contact the tip follows the surface. Where the surface falls away faster than
    the preload can accelerate the tip down (d^2 h/dt^2 < -preload), the tip leaves
    it with the surface's velocity and flies, z = z0 + v0 tau - preload tau^2 / 2,
    over whatever it passes, until it meets the surface again: an inelastic landing,
    the jump in velocity an impact.
    """
    surface_m = np.asarray(surface_m, dtype=float)
    try:
        preload = np.broadcast_to(np.asarray(preload_m_s2, dtype=float), surface_m.shape)
    except ValueError:
        raise ValueError(f"tip_path: preload_m_s2 of shape {np.shape(preload_m_s2)} does not "
                         f"match the surface's {surface_m.shape}") from None
    if not np.all(preload > 0):
        i = int(np.argmin(np.where(np.isnan(preload), -np.inf, preload)))
        raise ValueError(f"tip_path: preload_m_s2 must be positive everywhere (a tip pressed "
                         f"with none never lands); {preload[i]:g} at sample {i}")
    dt = 1.0 / fs
    vel = np.gradient(surface_m, dt)
    acc = np.gradient(vel, dt)
    takeoffs = np.flatnonzero(acc < -preload)
    if takeoffs.size == 0:
        return surface_m
    tip = surface_m.copy()
    n = surface_m.size
    k = 0
    while k < takeoffs.size:
        i0 = int(takeoffs[k])
        span = 64
        while True:  # the flight, in windows that double until it lands
            end = min(n, i0 + 1 + span)
            tau = np.arange(1, end - i0) * dt
            # The load changes by < 2 % within a flight at load_scale >= 0.3: held.
            flight = surface_m[i0] + vel[i0] * tau - 0.5 * preload[i0] * tau * tau
            below = np.flatnonzero(flight <= surface_m[i0 + 1:end])
            if below.size or end == n:
                land = i0 + 1 + (int(below[0]) if below.size else end - i0 - 1)
                break
            span *= 2
        tip[i0 + 1:land] = flight[:land - i0 - 1]
        k = int(np.searchsorted(takeoffs, land))  # the next takeoff after landing
    return tip


def _resonance_sos(f_hz: float, zeta: float, fs: float) -> Array:
    """Base-excited mode: tip acceleration in, tool acceleration out (unit DC gain)."""
    w = 2 * np.pi * f_hz
    b, a = ss.bilinear([2 * zeta * w, w * w], [1.0, 2 * zeta * w, w * w], fs)
    return ss.tf2sos(b, a)


def generate_scan(
    texture: str | Texture, speed_mm_s: float, seconds: float = 8.0, seed: int = 0,
    fs_hz: float = 1000.0, hand_variation: float = 1.0, noise_m_s2: float = 0.01,
    friction: bool = False, force_noise_n: float = 0.003,
    load_scale: float = 1.0,
) -> Scan:
    """One stroke over ``texture`` at about ``speed_mm_s``: a Scan (not written).

    ``load_scale``: the hand's mean normal load over the texture's own (its preload
    scales with it). At 1 the textures hardly lose contact at the paper's speeds (brick
    from 30 mm/s, rarely, sandpaper_p320 at 40); at 0.3, a light touch, brick does from
    20 mm/s, sandpaper_p320 from 25, sandpaper_p80 from 30, cork barely at 35-40
    (docs/texture.md, "The scan generator").
    ``scan.in_flight_share`` is the share of the stroke the tip spent off the surface.

    ``friction``: also ``force_n`` and ``friction_n`` (:func:`friction_forces`) under the
    hand's load (the one the preload follows, times ``load_scale``); the friction model
    keeps its contact through the tip's flights. The columns other than these two are the
    same with or without it.
    """
    if not (np.isfinite(load_scale) and load_scale > 0):
        raise ValueError(f"load_scale must be a positive number, not {load_scale!r}")
    tex = TEXTURES[texture] if isinstance(texture, str) else texture
    rng = np.random.default_rng([seed, zlib.crc32(tex.name.encode()), int(speed_mm_s * 100)])
    fs = SIM_FS_HZ
    v = hand_speed(speed_mm_s, seconds, fs, rng, hand_variation)
    n = v.size
    x0 = rng.uniform(0, max(1.0, SURFACE_MM - speed_mm_s * seconds * 1.5 - 1))
    x = x0 + np.cumsum(v) / fs
    prof = _profile(tex)
    z_mm = np.interp(x / DX_MM, np.arange(prof.size), prof)
    # The hand's normal load (relative to its mean) scales the preload; drawn from the
    # friction model's stream, which reads the same load for force_n.
    frng = np.random.default_rng([seed, zlib.crc32(tex.name.encode()),
                                  int(speed_mm_s * 100), 1])
    load = load_scale * hand_load(n, fs, frng)
    surface_m = z_mm * 1e-3
    z_m = tip_path(surface_m, tex.preload_m_s2 * load, fs)
    in_flight_share = float(np.mean(z_m > surface_m))
    # Vertical tip acceleration: second time derivative of the tip's path.
    az = np.gradient(np.gradient(z_m, 1 / fs), 1 / fs)
    # Stick-slip: releases at random slip distances along the path.
    ax = np.zeros(n)
    if tex.slip_mm > 0:
        dist = x - x0
        nslip = int(dist[-1] / tex.slip_mm * 1.5) + 2
        at = np.cumsum(tex.slip_mm * rng.gamma(4.0, 0.25, nslip))
        at = at[at < dist[-1]]
        k = np.searchsorted(dist, at)
        amp = tex.slip_m_s2 * rng.uniform(0.5, 1.5, k.size) * np.sqrt(
            np.maximum(v[k], 0.0) / 20.0) * fs / 1000.0
        np.add.at(ax, k, amp)
        np.add.at(ax, np.minimum(k + 3, n - 1), -amp)  # the rebound of a release
    # Friction couples the vertical motion into the tangential axis a little.
    ax += 0.3 * az
    ay = 0.15 * az + 0.1 * ax
    sos = _resonance_sos(tex.resonance_hz, tex.damping, fs)
    sos_t = _resonance_sos(tex.resonance_hz * 0.85, tex.damping, fs)
    acc = np.column_stack([ss.sosfilt(sos_t, ax), ss.sosfilt(sos_t, ay), ss.sosfilt(sos, az)])
    # Decimate to the output rate (anti-aliased, zero phase).
    q = round(fs / fs_hz)
    acc = ss.decimate(acc, q, ftype="fir", axis=0, zero_phase=True)
    v_out = v[::q][: acc.shape[0]]
    x_out = x[::q][: acc.shape[0]]
    m = acc.shape[0]
    t = np.arange(m) / fs_hz
    # slow hand motion and gravity through a slowly tilting hand
    slow = ss.sosfiltfilt(ss.butter(2, 2.0, fs=fs_hz, output="sos"),
                          rng.standard_normal((m, 3)), axis=0)
    slow *= 0.3 / (np.std(slow, axis=0) + 1e-12)
    tilt = 0.08 * np.sin(2 * np.pi * 0.2 * t + rng.uniform(0, 6.3))
    roll = 0.05 * np.sin(2 * np.pi * 0.13 * t + rng.uniform(0, 6.3))
    grav = G * np.column_stack([np.sin(tilt), np.sin(roll), np.cos(tilt) * np.cos(roll)])
    acc = acc + slow + grav
    acc = acc + noise_m_s2 * rng.standard_normal(acc.shape)
    scan = _with_position(tex, speed_mm_s, seed, t, acc, v_out, x_out)
    scan.in_flight_share = in_flight_share  # type: ignore[attr-defined]
    if load_scale != 1.0:  # said in the file's header (save_generated writes meta)
        scan.meta["load_scale"] = f"{load_scale:g}"
    if friction:
        forces = np.column_stack(friction_forces(tex, x, load))
        forces = ss.decimate(forces, q, ftype="fir", axis=0, zero_phase=True)[:m]
        forces += force_noise_n * frng.standard_normal(forces.shape)
        scan.force_n = forces[:, 0]
        scan.friction_n = forces[:, 1]  # type: ignore[attr-defined]
    return scan


def _with_position(tex: Texture, speed: float, seed: int, t: Array, acc: Array, v: Array,
                   x: Array) -> Scan:
    scan = Scan(path=f"{tex.name}_{speed:g}mms_s{seed}.csv", fs_hz=1.0 / (t[1] - t[0]),
                t_s=t, acc=acc, speed_mm_s=v,
                meta={"surface": tex.name, "tool": "synthetic-tip", "seed": str(seed)})
    scan.x_mm = x  # type: ignore[attr-defined]
    return scan


def save_generated(scan: Scan, path: str | Path) -> Path:
    """Write a generated scan (speed and position columns) as a texture scan CSV
    (docs/recording_format.md)."""
    x = getattr(scan, "x_mm", None)
    friction = getattr(scan, "friction_n", None)
    if friction is None:
        return write_scan(path, scan.t_s, scan.acc, scan.speed_mm_s, x_mm=x,
                          y_mm=None if x is None else np.zeros_like(x), meta=scan.meta)
    # With the friction model: all the contract's columns, in its order.
    names = ("t_s", "ax", "ay", "az", "speed_mm_s", "x_mm", "y_mm", "force_n", "friction_n")
    data = np.column_stack([scan.t_s, scan.acc, scan.speed_mm_s, x, np.zeros_like(x),
                            scan.force_n, friction])
    comment = " ".join(f"{k}={v}" for k, v in scan.meta.items()) or None
    with CsvRowWriter(path, names, comment=comment, flush_every_s=float("inf")) as w:
        for row in data:
            w.write(*(float(v) for v in row))
    return Path(path)


def write_scans(out_dir: Path, textures: str, speeds_mm_s: Sequence[float], strokes: int,
                seconds: float, seed: int, friction: bool, load_scale: float,
                wrap: Callable[[Iterable], Iterable] = lambda it: it) -> int:
    """``fydpad texture generate-scans``: ``strokes`` scans per texture (``textures``:
    comma-separated names or ``all``) and speed, ``SURFACE_SPEEDmms_sSEED.csv`` in
    ``out_dir``; returns how many."""
    names = list(TEXTURES) if textures == "all" else [
        n.strip() for n in textures.split(",") if n.strip()]
    unknown = [n for n in names if n not in TEXTURES]
    if unknown:
        raise UserError(f"--textures: unknown {', '.join(unknown)} (known: {', '.join(TEXTURES)})")
    if not (math.isfinite(load_scale) and load_scale > 0):
        raise UserError(f"--load-scale: give a positive number, not {load_scale:g}")
    jobs = [(n, s, seed + k) for n in names for s in speeds_mm_s for k in range(strokes)]
    for n, s, sd in wrap(jobs):
        scan = generate_scan(n, s, seconds, seed=sd, friction=friction, load_scale=load_scale)
        save_generated(scan, out_dir / f"{n}_{s:g}mms_s{sd}.csv")
    return len(jobs)


# --------------------------------------------------------------------------- friction
@dataclass(frozen=True)
class FrictionParams:
    """Friction of a surface against the tool (the friction family's scans)."""

    mu_kinetic: float = 0.45
    static_ratio: float = 1.15  # mu_s / mu_k: the stick-slip sawtooth's height
    material_variation: float = 0.08  # relative RMS of the material's mu along x
    variation_band_mm: tuple[float, float] = (0.5, 20.0)  # its wavelengths
    #: The tool's tangential stiffness (a stiff printed tip on a force sensor).
    stiffness_n_per_mm: float = 50.0
    load_n: float = 1.0  # mean normal load of the hand


FRICTION: dict[str, FrictionParams] = {
    "R1": FrictionParams(mu_kinetic=0.8), "R2": FrictionParams(mu_kinetic=0.8),
    "rubber": FrictionParams(mu_kinetic=1.0, static_ratio=1.3),
    "glass": FrictionParams(mu_kinetic=0.25, static_ratio=1.4),
    "felt": FrictionParams(mu_kinetic=0.6, material_variation=0.15),
}


def friction_params(texture: Texture) -> FrictionParams:
    return FRICTION.get(texture.name, FrictionParams())


def friction_truth(texture: str | Texture) -> tuple[Array, Array]:
    """Kinetic and static mu(x) of the tip on the DX_MM grid (the ground truth).

    Coulomb on an incline of slope s = dh/dx: sliding up (or down) a slope needs the
    tangential force F_n (mu + s) / (1 - mu s) for a vertical load F_n; the material's
    mu varies along x (band-limited, own random stream seeded by the name).
    """
    return _friction_truth(TEXTURES[texture] if isinstance(texture, str) else texture)


@functools.lru_cache(maxsize=32)  # keyed by the whole texture, as _profile
def _friction_truth(tex: Texture) -> tuple[Array, Array]:
    fp = friction_params(tex)
    rng = np.random.default_rng(zlib.crc32(f"{tex.name}/friction".encode()))
    n = int(SURFACE_MM / DX_MM)
    spec = np.fft.rfft(rng.standard_normal(n))
    k = np.fft.rfftfreq(n, DX_MM)
    lo, hi = 1.0 / fp.variation_band_mm[1], 1.0 / fp.variation_band_mm[0]
    r = np.fft.irfft(spec * ((k >= lo) & (k <= hi)), n)
    mat = fp.mu_kinetic * (1.0 + fp.material_variation * r / (np.std(r) + 1e-30))
    slope = np.gradient(_profile(tex), DX_MM)
    mu_k = (mat + slope) / (1.0 - mat * slope)
    mu_s = (fp.static_ratio * mat + slope) / (1.0 - fp.static_ratio * mat * slope)
    return mu_k, mu_s


def friction_mu_true(texture: str | Texture) -> Array:
    """The coefficient a slow, steady slide measures: the stick-slip sawtooth's mean
    (mu_k + mu_s) / 2 at each tip position, on the DX_MM grid from x = 0."""
    mu_k, mu_s = friction_truth(texture)
    return 0.5 * (mu_k + mu_s)


def friction_forces(tex: Texture, x_mm: Array, relative_load: Array) -> tuple[Array, Array]:
    """(normal force, friction force) in N at each sample of the hand's path ``x_mm``.

    The hand pulls the contact through a spring of stiffness k; the contact sticks
    until the spring force reaches mu_s F_n, then slips to mu_k F_n (instantaneous).
    Each sample reports the force averaged over its interval (a force sensor's
    averaging), computed exactly for any number of slips within the sample. The normal
    force is the texture's load times ``relative_load`` (the hand's, :func:`hand_load`,
    at each sample of ``x_mm``).
    """
    fp = friction_params(tex)
    mu_k, mu_s = friction_truth(tex)
    n = x_mm.size
    load = fp.load_n * relative_load
    k = fp.stiffness_n_per_mm
    xs = x_mm.tolist()
    fn = load.tolist()
    muk, mus = mu_k.tolist(), mu_s.tolist()
    last = len(muk) - 1
    out = [0.0] * n
    f = muk[min(int(xs[0] / DX_MM), last)] * fn[0]  # sliding at start
    for i in range(1, n):
        d = xs[i] - xs[i - 1]
        if d <= 0.0:  # the hand holds: the contact sticks, the force stays
            out[i] = f
            continue
        j = min(int((xs[i - 1] - f / k) / DX_MM), last)  # the tip's grid cell
        fs_, fk = mus[j] * fn[i], muk[j] * fn[i]
        if f + k * d <= fs_:  # sticks throughout
            out[i] = f + 0.5 * k * d
            f += k * d
            continue
        a = max((fs_ - f) / k, 0.0)  # travel to the first slip
        cyc = max((fs_ - fk) / k, 1e-12)  # travel per stick-slip cycle
        m, r = divmod(d - a, cyc)
        area = a * (f + fs_) / 2 + m * cyc * (fs_ + fk) / 2 + r * (fk + k * r / 2)
        out[i] = area / d
        f = fk + k * r
    out[0] = out[1]
    return load, np.asarray(out)


def plateau_speed(plateaus_mm_s: Sequence[float], seconds: float, fs: float,
                  rng: np.random.Generator, ramp_s: float = 1.0,
                  variation: float = 1.0) -> Array:
    """A hand stroke through speed plateaus: equal shares of ``seconds``, a cosine ramp of
    ``ramp_s`` between neighbours, and the hand's sway and drift (:func:`hand_speed`)."""
    n = round(seconds * fs)
    t = np.arange(n) / fs
    each = seconds / len(plateaus_mm_s)
    target = np.full(n, float(plateaus_mm_s[0]))
    for k in range(1, len(plateaus_mm_s)):
        w = np.clip((t - k * each + ramp_s / 2) / ramp_s, 0.0, 1.0)
        target += (plateaus_mm_s[k] - plateaus_mm_s[k - 1]) * (0.5 - 0.5 * np.cos(np.pi * w))
    return target * hand_speed(1.0, seconds, fs, rng, variation)[:n]


def penn_scan(ms: PennModelSet, speed_mm_s: Array, seed: int, force_n: float = 1.0,
              block_s: float = 0.05) -> Scan:
    """A stroke rendered from a HaTT model (:mod:`penn`) along ``speed_mm_s`` at the
    model's rate, with what the model does not hold: the hand's load wandering the force,
    contact impacts (one per 0.5-2 mm travelled), a tool resonance (seeded by the
    material's name, 250-420 Hz), the three axes' coupling, the hand's slow motion and
    gravity through a tilting hand, and sensor noise."""

    fs = ms.fs_hz
    v = np.asarray(speed_mm_s, float)
    n = v.size
    rng = np.random.default_rng([seed, zlib.crc32(ms.name.encode())])
    surf = np.random.default_rng(zlib.crc32(ms.name.encode()))  # the tool on this surface
    f_res, zeta = surf.uniform(250.0, 420.0), surf.uniform(0.08, 0.2)
    load = force_n * hand_load(n, fs, rng)
    step = max(1, round(block_s * fs))
    r = PennRenderer(ms, seed=int(rng.integers(2**31)))
    y = np.concatenate([r.block(float(np.mean(v[k:k + step])), float(np.mean(load[k:k + step])),
                                min(step, n - k)) for k in range(0, n, step)])
    # An impact is 3x the texture's RMS where it happens (over the surrounding 1 s), so a
    # surface at a given speed and force is the same whatever else the stroke visits (a
    # stroke's overall RMS is its fastest part's: up to 26 dB over its slow part's).
    win = np.ones(min(n, round(fs)))
    j = np.arange(n) + (win.size - 1) // 2  # "same" output i is the full convolution's j
    count = np.minimum(n - 1, j) - np.maximum(0, j - win.size + 1) + 1  # samples in window
    rms = np.sqrt(np.convolve(y * y, win, "same") / count) + 1e-9
    dist = np.cumsum(v) / fs
    at = np.cumsum(rng.uniform(0.5, 2.0, int(dist[-1] / 0.5) + 2))
    k = np.searchsorted(dist, at[at < dist[-1]])
    np.add.at(y, k, 3.0 * rms[k] * rng.uniform(0.5, 1.5, k.size) * np.sqrt(v[k] / 20.0))
    az = ss.sosfilt(_resonance_sos(f_res, zeta, fs), y)
    tang = ss.sosfilt(_resonance_sos(0.85 * f_res, zeta, fs), y)
    acc = np.column_stack([0.3 * tang, 0.15 * tang, az])
    t = np.arange(n) / fs
    slow = ss.sosfiltfilt(ss.butter(2, 2.0, fs=fs, output="sos"), rng.standard_normal((n, 3)),
                          axis=0)
    slow *= 0.3 / (np.std(slow, axis=0) + 1e-12)
    tilt = 0.08 * np.sin(2 * np.pi * 0.2 * t + rng.uniform(0, 6.3))
    roll = 0.05 * np.sin(2 * np.pi * 0.13 * t + rng.uniform(0, 6.3))
    grav = G * np.column_stack([np.sin(tilt), np.sin(roll), np.cos(tilt) * np.cos(roll)])
    acc = acc + slow + grav + 0.01 * rng.standard_normal(acc.shape)
    return Scan(path=f"{ms.name}_s{seed}.csv", fs_hz=fs, t_s=t, acc=acc, speed_mm_s=v,
                force_n=load, meta={"surface": ms.name, "tool": "hatt-render",
                                    "seed": str(seed)})
