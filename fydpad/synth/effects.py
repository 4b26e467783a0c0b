"""The conditions of real footage, each a flag, all combinable.

``Effects`` names which are on. The ones that change the light over time are small
deterministic processes drawn once from the session's Generator:

- ``RoomLight``: the room light dips to 2/3 for 1.5-3.5 s now and then (someone stands
  in the light, a lamp is switched), and flickers: mains ripple at 100 Hz integrated
  over the exposure (mean of cos over the exposure = cos(2 pi f t) sinc(f E)), which
  beats with the frame rate, plus bursts of a failing tube dimming single frames;
- ``AutoExposure``: the camera's gain hunts, a smooth swing of up to +-20 %, and chases
  the room light's dips with a lag (so a dip is followed by a partial, late recovery);
- ``Daylight``: light from one side, a linear gradient of +-A across the frame whose
  direction and strength drift slowly;
- ``HandShadow``: the rest of the hand (palm, curled fingers, thumb) above the fabric
  near the user, a large blurred shadow entering the view from its user edge and
  moving with the finger;
- ``PalmRest``: the heel of the palm resting on the fabric at the user's edge when the
  recording starts, pressed on it (a large dark patch as sharp as a contact), lifted
  after 1-2 s (its shadow blurs and pales as it rises).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from fydpad.synth.finger import _soft_inside
from fydpad.synth.geometry import CameraGeometry

#: Command-line name and one-line help of every effect flag (``--NAME``).
EFFECT_HELP: dict[str, str] = {
    "uneven_light": "uneven, strongly vignetted backlight (corners ~35 % darker, a lamp's "
                    "hotspot, blotches)",
    "room_light": "room light dipping by a third for seconds, mains flicker and bursts",
    "auto_exposure": "camera auto-exposure hunting: the whole image swings by up to +-20 %",
    "daylight": "daylight from one side: a brightness gradient whose side and strength drift",
    "stains": "ink dots, pen lines and a dried stain on the fabric, darker than grey 150",
    "hover": "the finger travels 3 mm above the fabric between contacts and its shadow is dark "
             "(below grey 150 when close)",
    "hand_shadow": "the rest of the hand shadows the user's edge of the view",
    "light_touch": "light touches: indentations under ~1.5 mm and a pale contact",
    "fast": "fast strokes: finger speed up to 45 mm/s and a 1/30 s exposure",
    "palm_rest": "the heel of the palm rests on the fabric at the user's edge at the start, "
                 "lifted after 1-2 s",
}


@dataclass(frozen=True)
class Effects:
    """Which real-footage conditions to render (all off: clean footage)."""

    uneven_light: bool = False
    room_light: bool = False
    auto_exposure: bool = False
    daylight: bool = False
    stains: bool = False
    hover: bool = False
    hand_shadow: bool = False
    light_touch: bool = False
    fast: bool = False
    palm_rest: bool = False

    @classmethod
    def all(cls) -> Effects:
        return cls(**{f.name: True for f in fields(cls)})

    def names(self) -> list[str]:
        return [f.name for f in fields(self) if getattr(self, f.name)]


def _smooth_swing(rng: np.random.Generator, periods_s: tuple[float, float], n: int = 3
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Random (amplitudes, angular frequencies, phases) of a sum of n sines whose
    amplitudes sum to 1 (so the swing stays within +-1)."""
    amp = rng.uniform(0.5, 1.0, n)
    return (amp / amp.sum(), 2 * np.pi / rng.uniform(*periods_s, n),
            rng.uniform(0, 2 * np.pi, n))


def _sines(t_s: float, a: NDArray[np.float64], w: NDArray[np.float64],
           ph: NDArray[np.float64]) -> float:
    return float(np.sum(a * np.sin(w * t_s + ph)))


class RoomLight:
    """Global light level over time: dips to 2/3 and flicker (a factor per frame)."""

    def __init__(self, rng: np.random.Generator, duration_s: float, exposure_s: float,
                 start_s: float = 1.0, dip_depth: float = 1.0 / 3.0,
                 ripple: float = 0.25, mains_hz: float = 100.0):
        self.exposure_s = exposure_s
        self.dip_depth = dip_depth
        self.ripple = ripple
        self.mains_hz = mains_hz
        self.ripple_phase = rng.uniform(0, 2 * np.pi)
        # Dips: one every ~5 s on average, the first soon after the start.
        dips = []
        t = start_s + rng.uniform(0.0, 1.5)
        while t < duration_s:
            length = rng.uniform(1.5, 3.5)
            dips.append((t, t + length))
            t += length + rng.uniform(1.5, 4.0)
        self.dips = dips
        # Flicker bursts of a failing tube: ~0.7 per second, 1-3 frames long.
        n_bursts = rng.poisson(0.7 * max(duration_s, 0.0))
        starts = np.sort(rng.uniform(0, max(duration_s, 1e-9), n_bursts))
        self.bursts = [(float(s), float(s + rng.integers(1, 4) / 30.0),
                        float(rng.uniform(0.7, 0.9))) for s in starts]

    def dip_gain(self, t_s: float) -> float:
        """1 outside the dips, 1 - depth inside, raised-cosine edges of 0.25 s."""
        edge = 0.25
        g = 1.0
        for t0, t1 in self.dips:
            if t0 - edge < t_s < t1 + edge:
                rise = min(max((t_s - t0 + edge) / edge, 0.0), 1.0)
                fall = min(max((t1 + edge - t_s) / edge, 0.0), 1.0)
                f = min(rise, fall)
                g = min(g, 1.0 - self.dip_depth * 0.5 * (1 - np.cos(np.pi * f)))
        return g

    def gain(self, t_s: float) -> float:
        # Ripple integrated over the exposure: cos(2 pi f t) * sinc(f E).
        ripple = self.ripple * np.cos(2 * np.pi * self.mains_hz * t_s + self.ripple_phase) \
            * np.sinc(self.mains_hz * self.exposure_s)
        burst = 1.0
        for s0, s1, depth in self.bursts:
            if s0 <= t_s < s1:
                burst = depth
        return self.dip_gain(t_s) * (1.0 + float(ripple)) * burst


class AutoExposure:
    """The camera's auto-exposure: it hunts (a smooth random swing, periods 1.5-5 s)
    and, when the room light changes, chases it with a lag: its gain is
    clip((1 / L_seen)^c x (1 + swing s(t)), 1 - swing, 1 + swing), where L_seen is the
    room light low-passed over ``lag_s`` and c how much of a change it makes up for.
    The gain never leaves +-``swing``."""

    def __init__(self, rng: np.random.Generator, swing: float = 0.2,
                 room: RoomLight | None = None, lag_s: float = 0.6,
                 compensation: float = 0.6):
        self.swing = swing
        self.room = room
        self.lag_s = lag_s
        self.compensation = compensation
        self.a, self.w, self.ph = _smooth_swing(rng, (1.5, 5.0))

    def seen_light(self, t_s: float) -> float:
        """Room light low-passed by the AE loop: exp(-tau/lag)-weighted past (3 lags)."""
        if self.room is None:
            return 1.0
        tau = np.linspace(0.0, 3.0 * self.lag_s, 31)
        w = np.exp(-tau / self.lag_s)
        levels = np.array([self.room.dip_gain(t_s - x) for x in tau])
        return float(np.sum(w * levels) / np.sum(w))

    def gain(self, t_s: float) -> float:
        hunt = 1.0 + self.swing * _sines(t_s, self.a, self.w, self.ph)
        chase = self.seen_light(t_s) ** -self.compensation
        return float(np.clip(chase * hunt, 1.0 - self.swing, 1.0 + self.swing))


class Daylight:
    """A side light: gain 1 + A(t) (cos th(t) x_n + sin th(t) y_n), x_n, y_n in [-1, 1]
    across the frame; A drifts in 0.15-0.3 and th by +-0.5 rad around a random side."""

    def __init__(self, rng: np.random.Generator, geom: CameraGeometry):
        w, h = geom.frame_size
        self._xn = np.linspace(-1, 1, w, dtype=np.float32)[None, :]
        self._yn = np.linspace(-1, 1, h, dtype=np.float32)[:, None]
        self.theta0 = rng.uniform(0, 2 * np.pi)
        self.a_amp = _smooth_swing(rng, (6.0, 15.0), 2)
        self.th_amp = _smooth_swing(rng, (8.0, 20.0), 2)

    def strength(self, t_s: float) -> float:
        return 0.225 + 0.075 * _sines(t_s, *self.a_amp)

    def angle(self, t_s: float) -> float:
        return self.theta0 + 0.5 * _sines(t_s, *self.th_amp)

    def field(self, t_s: float) -> NDArray[np.float32]:
        a, th = self.strength(t_s), self.angle(t_s)
        return (1.0 + np.float32(a * np.cos(th)) * self._xn) + np.float32(a * np.sin(th)) \
            * self._yn


@dataclass(frozen=True)
class HandPart:
    """One part of the hand as a blurred elliptical shadow, placed relative to the
    fingertip (x mirrored for a left hand)."""

    offset_mm: tuple[float, float]
    axes_mm: tuple[float, float]
    darkness: float


@dataclass(frozen=True)
class HandShadowParams:
    parts: tuple[HandPart, ...] = (
        HandPart((10.0, -46.0), (34.0, 24.0), 0.5),   # palm
        HandPart((22.0, -30.0), (11.0, 14.0), 0.45),  # the other fingers, curled
        HandPart((-28.0, -34.0), (9.0, 16.0), 0.4),   # thumb
    )
    #: The hand is 20-40 mm above the fabric: a wide penumbra.
    blur_mm: float = 7.0


class HandShadow:
    """The hand's shadow: palm, curled fingers and thumb, placed from the fingertip."""

    def __init__(self, rng: np.random.Generator, geom: CameraGeometry,
                 p: HandShadowParams = HandShadowParams()):
        self.geom = geom
        self.p = p
        self.side = 1.0 if rng.uniform() < 0.7 else -1.0  # right hand (thumb left) mostly
        self.jitter = rng.uniform(-4.0, 4.0, 2)

    def apply(self, lum: NDArray[np.float32], x_mm: float, y_mm: float, z_mm: float) -> None:
        p = self.p
        # The hand is lower (darker shadow) when the finger presses than when it is raised.
        fade = float(np.exp(-max(-z_mm, 0.0) / 40.0))
        h = self.geom.frame_size[1]
        # Only the lower part of the view can be reached: work on those rows.
        y_top = y_mm + max(q.offset_mm[1] + q.axes_mm[1] for q in p.parts) \
            + float(self.jitter[1]) + 3.0 * p.blur_mm
        rows = self.geom.box(0.0, y_top, 1.0, 0.0)[0]
        rows = slice(rows.start, h)
        if rows.start >= h:
            return
        gx, gy = self.geom.grid(rows, slice(0, self.geom.frame_size[0]))
        blocked = np.zeros((h - rows.start, self.geom.frame_size[0]), np.float32)
        for q in p.parts:
            ax, ay = q.axes_mm
            cx = x_mm + self.side * q.offset_mm[0] + self.jitter[0]
            cy = y_mm + q.offset_mm[1] + self.jitter[1]
            r = np.sqrt(((gx - cx) / ax) ** 2 + ((gy - cy) / ay) ** 2)
            part = q.darkness * fade * _soft_inside((r - 1.0) * 0.5 * (ax + ay), p.blur_mm)
            blocked = 1.0 - (1.0 - blocked) * (1.0 - part)
        lum[rows] *= 1.0 - blocked


class PalmRest:
    """The heel of the palm on the fabric at the user's edge: an ellipse of 28 x 16 mm
    semi-axes centred 6 mm inside the near edge of the workspace, pressed (transmission
    1 - 0.6, a 1 mm edge) until ``lift_s``, then rising over 0.4 s: its shadow pales to 0
    and its edge blurs to 8 mm."""

    def __init__(self, rng: np.random.Generator, geom: CameraGeometry,
                 axes_mm: tuple[float, float] = (28.0, 16.0), darkness: float = 0.6):
        self.geom = geom
        self.axes_mm = axes_mm
        self.darkness = darkness
        self.x_mm = float(rng.uniform(-0.25, 0.25) * geom.workspace_mm[0])
        self.y_mm = -0.5 * geom.workspace_mm[1] + 6.0 - axes_mm[1] * 0.3
        self.lift_s = float(rng.uniform(1.0, 2.0))
        self.rise_s = 0.4

    def apply(self, lum: NDArray[np.float32], t_s: float) -> None:
        up = (t_s - self.lift_s) / self.rise_s
        if up >= 1.0:
            return
        up = max(up, 0.0)
        darkness = self.darkness * (1.0 - up)
        blur = 1.0 + 7.0 * up
        ax, ay = self.axes_mm
        rows, cols = self.geom.box(self.x_mm, self.y_mm, ax + 3 * blur, ay + 3 * blur)
        if rows.start >= rows.stop or cols.start >= cols.stop:
            return
        gx, gy = self.geom.grid(rows, cols)
        r = np.sqrt(((gx - self.x_mm) / ax) ** 2 + ((gy - self.y_mm) / ay) ** 2)
        part = np.float32(darkness) * _soft_inside((r - 1.0) * np.float32(0.5 * (ax + ay)),
                                                    blur)
        lum[rows, cols] *= 1.0 - part
