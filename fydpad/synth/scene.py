"""The still parts of the picture, computed once per session: backlight, weave, marks.

The camera sees light transmitted through the fabric: grey = exposure x backlight(u, v)
x fabric transmission(u, v) x everything in the way (finger, hand). The backlight is
the room light diffused by the fabric, with the lens's vignetting (cos^4-like falloff,
approximated as 1 - k r^2); the fabric's transmission has the weave (threads finer than
a pixel, so they alias into a fine moire), slow density variations, and a fixed per-pixel
grain. Marks (ink dots, pen lines, a dried stain) block light where they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from fydpad.synth.geometry import CameraGeometry


@dataclass(frozen=True)
class BacklightParams:
    """Light reaching the camera through the fabric, in grey levels."""

    #: Grey level of the bare fabric at the optical centre.
    level: float = 212.0
    #: Vignetting: relative fall-off at the frame's corners (1 - k r^2, r = 1 at a corner).
    vignette: float = 0.10
    #: Optical centre offset, as a fraction of the frame size.
    centre_offset: tuple[float, float] = (0.0, 0.0)
    #: A brighter spot where the room's lamp is (relative amplitude, sigma in pixels).
    hotspot: float = 0.0
    hotspot_sigma_px: float = 140.0
    #: Low-frequency unevenness of the light (relative, RMS) and its scale in pixels.
    blotches: float = 0.0
    blotch_scale_px: float = 60.0


@dataclass(frozen=True)
class WeaveParams:
    """The fabric's texture in transmission."""

    amplitude: float = 0.05
    period_px: tuple[float, float] = (3.1, 3.7)
    angle_deg: float = 3.0
    #: Slow density variations of the fabric (relative RMS, scale in pixels).
    density: float = 0.015
    density_scale_px: float = 12.0
    #: Fixed per-pixel grain (relative RMS).
    grain: float = 0.012


UNEVEN_BACKLIGHT = BacklightParams(vignette=0.34, centre_offset=(0.08, -0.06), hotspot=0.12,
                                   blotches=0.06)


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], scale_px: float
                  ) -> NDArray[np.float32]:
    """Gaussian-filtered white noise normalised to unit RMS."""
    n = rng.standard_normal(shape, dtype=np.float32)
    n = cv2.GaussianBlur(n, (0, 0), scale_px, borderType=cv2.BORDER_REFLECT)
    return n / max(float(n.std()), 1e-9)


def backlight_field(geom: CameraGeometry, p: BacklightParams, rng: np.random.Generator
                    ) -> NDArray[np.float32]:
    """Backlight in grey levels at every pixel of the flipped frame."""
    w, h = geom.frame_size
    u = (np.arange(w, dtype=np.float32) + 0.5) / w - 0.5 - p.centre_offset[0]
    v = (np.arange(h, dtype=np.float32) + 0.5) / h - 0.5 - p.centre_offset[1]
    # r = 1 at a corner of an un-offset frame.
    r2 = (u[None, :] ** 2 + (v[:, None] * h / w) ** 2) / (0.25 + 0.25 * (h / w) ** 2)
    field = p.level * (1.0 - p.vignette * r2)
    if p.hotspot:
        hx, hy = rng.uniform(0.25, 0.75) * w, rng.uniform(0.25, 0.75) * h
        du = np.arange(w, dtype=np.float32) - hx
        dv = np.arange(h, dtype=np.float32) - hy
        field = field * (1.0 + p.hotspot * np.exp(-(du[None, :] ** 2 + dv[:, None] ** 2)
                                                 / (2 * p.hotspot_sigma_px ** 2)))
    if p.blotches:
        field = field * (1.0 + p.blotches * _smooth_noise(rng, (h, w), p.blotch_scale_px))
    return field.astype(np.float32)


def weave_field(geom: CameraGeometry, p: WeaveParams, rng: np.random.Generator
                ) -> NDArray[np.float32]:
    """The fabric's transmission (mean 1) at every pixel."""
    w, h = geom.frame_size
    a = np.deg2rad(p.angle_deg + rng.uniform(-1.0, 1.0))
    u = np.arange(w, dtype=np.float32)[None, :]
    v = np.arange(h, dtype=np.float32)[:, None]
    warp = np.cos(2 * np.pi * (u * np.cos(a) + v * np.sin(a)) / p.period_px[0])
    weft = np.cos(2 * np.pi * (-u * np.sin(a) + v * np.cos(a)) / p.period_px[1])
    t = 1.0 + p.amplitude * warp * weft
    t = t * (1.0 + p.density * _smooth_noise(rng, (h, w), p.density_scale_px))
    t = t * (1.0 + p.grain * rng.standard_normal((h, w), dtype=np.float32))
    return t.astype(np.float32)


@dataclass(frozen=True)
class StainParams:
    """Marks on the fabric; every one blocks enough light to fall below grey 150."""

    dots: int = 3
    lines: int = 2
    blotches: int = 1
    #: Transmission ranges of each kind (a bare fabric of ~210 under T = 0.7 is ~147).
    dot_transmission: tuple[float, float] = (0.3, 0.6)
    line_transmission: tuple[float, float] = (0.4, 0.62)
    blotch_transmission: tuple[float, float] = (0.55, 0.68)


def stain_field(geom: CameraGeometry, p: StainParams, rng: np.random.Generator
                ) -> NDArray[np.float32]:
    """Transmission of the marks (1 where there are none) at every pixel."""
    w, h = geom.frame_size
    x = geom.x_cols_mm[None, :]
    y = geom.y_rows_mm[:, None]
    t = np.ones((h, w), np.float32)
    half_w, half_h = geom.workspace_mm[0] / 2 + 3, geom.workspace_mm[1] / 2 + 3

    def where() -> tuple[float, float]:
        return float(rng.uniform(-half_w, half_w)), float(rng.uniform(-half_h, half_h))

    for _ in range(p.dots):
        cx, cy = where()
        r = rng.uniform(0.8, 2.5)
        d = np.sqrt((x - cx) ** 2 + (y - cy) ** 2) - r
        t *= 1.0 - (1.0 - rng.uniform(*p.dot_transmission)) * 0.5 * (1 - np.tanh(d / 0.25))
    for _ in range(p.lines):
        # A pen stroke: a slightly curved line segment 8-25 mm long, 0.5-1.2 mm wide.
        cx, cy = where()
        length, ang = rng.uniform(8.0, 25.0), rng.uniform(0, np.pi)
        bend = rng.uniform(-0.02, 0.02)
        ca, sa = np.cos(ang), np.sin(ang)
        along = (x - cx) * ca + (y - cy) * sa
        across = -(x - cx) * sa + (y - cy) * ca - bend * along ** 2
        half = rng.uniform(0.25, 0.6)
        d = np.maximum(np.abs(across) - half, np.abs(along) - length / 2)
        t *= 1.0 - (1.0 - rng.uniform(*p.line_transmission)) * 0.5 * (1 - np.tanh(d / 0.2))
    for _ in range(p.blotches):
        # A dried drop: a pale disc with a darker rim (the coffee-ring effect).
        cx, cy = where()
        r = rng.uniform(4.0, 8.0)
        rho = np.sqrt((x - cx) ** 2 + ((y - cy) * rng.uniform(0.8, 1.2)) ** 2)
        dark = 1.0 - rng.uniform(*p.blotch_transmission)
        disc = 0.5 * (1 - np.tanh((rho - r) / 0.4))
        rim = np.exp(-((rho - r + 0.6) / 0.5) ** 2)
        t *= 1.0 - np.clip(dark * disc + 0.35 * dark * rim, 0.0, 0.9)
    return t.astype(np.float32)
