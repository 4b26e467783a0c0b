"""What the under-fabric camera sees of a finger: light it blocks from the backlight.

The room light comes from above, passes through the fabric and reaches the camera
below; a finger on or above the fabric blocks part of it. Each part of the finger is a
transmission factor T in [0, 1] multiplying the light (so effects compose by product):

- the **contact** (the fabric wrapped around the fingertip): an ellipse, longer along
  the finger (``aspect``), whose radius grows with indentation as the fabric model's
  ``contact_radius_mm`` (a sphere wrapping the fabric), darkest in its middle
  (``1 - D (1 - c r^2)``), soft-edged (the fabric diffuses light sideways);
  its darkness D saturates over the first fraction of a millimetre of indentation;
- the **fingertip's shadow** above the fabric: the tip's footprint blurred by a
  penumbra that widens with height h (sigma = blur0 + k h), fading as exp(-h / h0);
  it is the whole finger's image while it hovers, a soft halo around a contact;
- the **rest of the finger**: a pale, blurred band from the tip towards the hand
  (towards the user, down in the from-above image), fading with distance.

Motion blur: the contact is integrated over sub-frame positions; the shadows are soft
enough that their position at mid-exposure stands for the exposure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.fabric import Fabric
from fydpad.synth.geometry import CameraGeometry


@dataclass(frozen=True)
class FingerLook:
    """Optical parameters of the finger (fractions of light blocked, lengths in mm)."""

    #: Fraction of light a firm contact blocks at its centre (rest ~210 -> ~70 grey).
    contact_darkness: float = 0.66
    #: The contact's darkness reaches 63 % of its full value at this indentation.
    onset_mm: float = 0.25
    #: Darkness falls from the centre as 1 - centre_falloff r^2 (r: elliptical radius).
    centre_falloff: float = 0.3
    #: Smallest contact radius (the skin's own flattening as it touches).
    min_radius_mm: float = 1.2
    #: Across-finger semi-axis over the fabric model's contact radius; along is times aspect.
    across_scale: float = 0.9
    aspect: float = 1.25
    #: Beyond the fingertip's radius the fabric keeps wrapping the finger's sides: the
    #: contact keeps growing by this much per mm of deeper indentation.
    wrap_mm_per_mm: float = 0.12
    #: Soft edge half-width of the contact, mm.
    edge_mm: float = 0.9
    #: Fingertip shadow: fraction blocked as the tip nears the fabric, its decay height,
    #: the tip footprint (across, along semi-axes) and the penumbra law.
    tip_shadow: float = 0.12
    tip_height_mm: float = 6.0
    tip_axes_mm: tuple[float, float] = (7.5, 9.5)
    tip_blur_mm: float = 1.2
    tip_blur_per_mm: float = 0.45
    #: Shadow of the rest of the finger: fraction blocked, half-width, fade length, blur.
    body_shadow: float = 0.11
    body_half_width_mm: float = 8.0
    body_fade_mm: float = 55.0
    body_blur_mm: float = 3.0
    #: Where the hand is (workspace mm): the finger points from it to the fingertip.
    hand_xy_mm: tuple[float, float] = (12.0, -120.0)


def _soft_inside(dist_mm: NDArray[np.float32], blur_mm: float | NDArray[np.float32]
                 ) -> NDArray[np.float32]:
    """1 well inside (dist < 0), 0 well outside, a tanh ramp of half-width ~blur."""
    return 0.5 * (1.0 - np.tanh(dist_mm / blur_mm))


def finger_axis(x_mm: float, y_mm: float, look: FingerLook) -> tuple[float, float]:
    """Unit vector along the finger from the tip towards the hand."""
    dx, dy = look.hand_xy_mm[0] - x_mm, look.hand_xy_mm[1] - y_mm
    n = float(np.hypot(dx, dy)) or 1.0
    return dx / n, dy / n


def contact_darkness(z_mm: float, look: FingerLook, darkness: float | None = None) -> float:
    """Centre darkness of the contact at indentation z (0 when not touching)."""
    if z_mm <= 0:
        return 0.0
    full = look.contact_darkness if darkness is None else darkness
    return full * (1.0 - np.exp(-z_mm / look.onset_mm))


def contact_axes_mm(z_mm: float, look: FingerLook, fabric: Fabric) -> tuple[float, float]:
    """(across, along) semi-axes of the contact ellipse at indentation z."""
    a = max(float(fabric.contact_radius_mm(z_mm)), look.min_radius_mm)
    a += look.wrap_mm_per_mm * max(z_mm - 0.5 * fabric.finger_radius_mm, 0.0)
    return a * look.across_scale, a * look.across_scale * look.aspect


def render_contact(
    lum: NDArray[np.float32], geom: CameraGeometry, look: FingerLook, fabric: Fabric,
    xs: NDArray[np.float64], ys: NDArray[np.float64], zs: NDArray[np.float64],
    darkness: float | None = None,
) -> None:
    """Multiply ``lum`` by the contact's transmission averaged over the sub-frame
    positions (xs, ys, zs): the exposure integrates the moving dark patch."""
    touching = zs > 0
    if not np.any(touching):
        return
    xt, yt, zt = xs[touching], ys[touching], zs[touching]
    reach = max(contact_axes_mm(float(zt.max()), look, fabric)) + 3.0 * look.edge_mm + 1.0
    rows, cols = geom.box(float(xt.mean()), float(yt.mean()),
                          reach + 0.5 * float(np.ptp(xt)), reach + 0.5 * float(np.ptp(yt)))
    if rows.start >= rows.stop or cols.start >= cols.stop:
        return
    gx, gy = geom.grid(rows, cols)
    blocked = np.zeros((rows.stop - rows.start, cols.stop - cols.start), np.float32)
    for x, y, z in zip(xs, ys, zs, strict=True):
        d = contact_darkness(float(z), look, darkness)
        if d <= 0:
            continue  # this part of the exposure saw no contact
        ux, uy = finger_axis(float(x), float(y), look)
        dx, dy = gx - np.float32(x), gy - np.float32(y)
        s = dx * ux + dy * uy
        c = dy * ux - dx * uy
        a_c, a_s = contact_axes_mm(float(z), look, fabric)
        r = np.sqrt((c / a_c) ** 2 + (s / a_s) ** 2)
        # Distance from the ellipse edge, in mm, along the mean semi-axis.
        dist = (r - 1.0) * np.float32(0.5 * (a_c + a_s))
        blocked += np.float32(d) * (1.0 - look.centre_falloff * np.minimum(r, 1.0) ** 2) \
            * _soft_inside(dist, look.edge_mm)
    blocked /= np.float32(len(xs))
    lum[rows, cols] *= 1.0 - blocked


def render_shadows(
    lum: NDArray[np.float32], geom: CameraGeometry, look: FingerLook,
    x_mm: float, y_mm: float, z_mm: float, tip_shadow: float | None = None,
) -> None:
    """Multiply ``lum`` by the fingertip's and the finger's shadows at (x, y, z)."""
    h = max(-z_mm, 0.0)
    tip = look.tip_shadow if tip_shadow is None else tip_shadow
    a_tip = tip * np.exp(-h / look.tip_height_mm)
    # The whole finger rises with the fingertip: its shadow pales and blurs with height.
    a_body = look.body_shadow * np.exp(-h / 25.0)
    if a_tip < 2e-3 and a_body < 2e-3:
        return
    ux, uy = finger_axis(x_mm, y_mm, look)
    blur_tip = look.tip_blur_mm + look.tip_blur_per_mm * h
    # Box: around the tip, and down the finger towards the hand to the frame's edge.
    far = 120.0
    ex, ey = x_mm + ux * far, y_mm + uy * far
    # Far enough out that both soft edges have fallen to ~0 (tanh(3) = 0.995).
    blur_body_max = look.body_blur_mm + 0.04 * far + 0.3 * h
    margin = max(max(look.tip_axes_mm) + 1.5 + 3.0 * blur_tip,
                 look.body_half_width_mm + 3.0 * blur_body_max)
    x0, x1 = min(x_mm, ex) - margin, max(x_mm, ex) + margin
    y0, y1 = min(y_mm, ey) - margin, max(y_mm, ey) + margin
    rows, cols = geom.box(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (x1 - x0), 0.5 * (y1 - y0))
    if rows.start >= rows.stop or cols.start >= cols.stop:
        return
    gx, gy = geom.grid(rows, cols)
    dx, dy = gx - np.float32(x_mm), gy - np.float32(y_mm)
    s = dx * ux + dy * uy
    c = dy * ux - dx * uy
    blocked = np.zeros((rows.stop - rows.start, cols.stop - cols.start), np.float32)
    if a_tip >= 2e-3:
        ac, al = look.tip_axes_mm
        # Raised, the footprint's centre sits a little towards the fingertip's end (the
        # pulp is behind the tip); touching, it is centred on the contact the pulp makes.
        shift = 1.5 * min(h / 3.0, 1.0)
        r = np.sqrt((c / ac) ** 2 + ((s + shift) / al) ** 2)
        blocked += np.float32(a_tip) * _soft_inside((r - 1.0) * np.float32(0.5 * (ac + al)),
                                                    blur_tip)
    if a_body >= 2e-3:
        # Capsule from the tip towards the hand: distance to its axis (round end at the tip).
        sp = np.maximum(s, 0.0)
        dist = np.where(s > 0, np.abs(c), np.sqrt(s * s + c * c)) - look.body_half_width_mm
        blur = look.body_blur_mm + 0.04 * sp + 0.3 * h
        body = np.float32(a_body) * np.exp(-sp / look.body_fade_mm) * _soft_inside(dist, blur)
        # Light blocked by two overlapping parts of one finger does not add up past 1.
        blocked = 1.0 - (1.0 - blocked) * (1.0 - body)
    lum[rows, cols] *= 1.0 - blocked
