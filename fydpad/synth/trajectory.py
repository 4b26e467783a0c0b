"""Finger trajectories for the synthetic pad, sampled densely in time.

A trajectory is the fingertip's path in the workspace frame (x, y in mm) and a signed
``z_mm``: positive is the indentation of the fabric (the finger touches), negative is
the fingertip's height above the flat fabric (no contact). Paths are built from
minimum-jerk moves (s = 10 tau^3 - 15 tau^4 + 6 tau^5, peak speed 1.875 d / T), so
speeds are smooth and their peaks are set exactly. Every trajectory starts with the
finger far above the fabric (no-contact frames for the IR baselines), then approaches,
and contact onsets and releases are smooth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad import indentation_protocol as proto

TRAJECTORIES = ("circle", "lissajous", "tapping", "walk", "fast", "hover", "presses",
                "protocol")

#: Peak speed of a minimum-jerk move over its mean speed.
_MIN_JERK_PEAK = 1.875


@dataclass(frozen=True)
class TrajectoryParams:
    """Knobs shared by every trajectory (the effects adjust some of them)."""

    #: Peak finger speed in the fabric plane (paper: tracking is good up to 40 mm/s).
    max_speed_mm_s: float = 40.0
    #: Peak speed of the finger along z when it taps or presses.
    max_z_speed_mm_s: float = 80.0
    #: Height above the fabric while the finger travels between contacts.
    travel_height_mm: float = 15.0
    #: Height of the finger before it comes to the pad (far: barely any shadow).
    far_height_mm: float = 45.0
    #: Time at the start with the finger far above the fabric (IR baselines).
    lead_in_s: float = 0.8
    #: Light touches: indentations squeezed into 0-``light_max_mm`` (None: off).
    light_max_mm: float | None = None
    #: Half-size of the area the finger is kept in (inside the 100 x 70 mm workspace).
    reach_mm: tuple[float, float] = (40.0, 27.0)


@dataclass(frozen=True)
class FingerPath:
    """The finger sampled every ``dt_s`` from t = 0: x_mm, y_mm and signed z_mm."""

    dt_s: float
    x_mm: NDArray[np.float64]
    y_mm: NDArray[np.float64]
    z_mm: NDArray[np.float64]

    @property
    def duration_s(self) -> float:
        return (self.x_mm.size - 1) * self.dt_s

    def at(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                          NDArray[np.float64]]:
        """(x_mm, y_mm, z_mm) at times ``t_s`` (linear interpolation, held at the ends)."""
        t = np.asarray(t_s, np.float64)
        grid = np.arange(self.x_mm.size) * self.dt_s
        return (np.interp(t, grid, self.x_mm), np.interp(t, grid, self.y_mm),
                np.interp(t, grid, self.z_mm))

    def indentation_mm(self, t_s: ArrayLike) -> NDArray[np.float64]:
        return np.maximum(self.at(t_s)[2], 0.0)

    def speed_mm_s(self) -> NDArray[np.float64]:
        """In-plane speed at every sample."""
        return np.hypot(np.gradient(self.x_mm, self.dt_s), np.gradient(self.y_mm, self.dt_s))


class PathBuilder:
    """Appends moves to a path sampled at ``rate_hz``."""

    def __init__(self, x_mm: float, y_mm: float, z_mm: float, rate_hz: float = 1000.0):
        self.dt_s = 1.0 / rate_hz
        self._chunks: list[NDArray[np.float64]] = [np.array([[x_mm, y_mm, z_mm]])]

    @property
    def pos(self) -> NDArray[np.float64]:
        return self._chunks[-1][-1]

    @property
    def t_s(self) -> float:
        return (sum(c.shape[0] for c in self._chunks) - 1) * self.dt_s

    def _n(self, duration_s: float) -> int:
        return max(round(duration_s / self.dt_s), 1)

    def move(self, x_mm: float, y_mm: float, z_mm: float, duration_s: float) -> PathBuilder:
        """Minimum-jerk move to (x, y, z) over ``duration_s``."""
        n = self._n(duration_s)
        tau = np.arange(1, n + 1) / n
        s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        p0 = self.pos
        p1 = np.array([x_mm, y_mm, z_mm])
        self._chunks.append(p0 + s[:, None] * (p1 - p0))
        return self

    def move_at(self, x_mm: float, y_mm: float, z_mm: float, speed_mm_s: float,
                z_speed_mm_s: float, min_s: float = 0.15) -> PathBuilder:
        """Minimum-jerk move whose peak speeds stay under the given in-plane and z speeds."""
        p0 = self.pos
        dxy = float(np.hypot(x_mm - p0[0], y_mm - p0[1]))
        dz = abs(z_mm - p0[2])
        t = max(_MIN_JERK_PEAK * dxy / speed_mm_s, _MIN_JERK_PEAK * dz / z_speed_mm_s, min_s)
        return self.move(x_mm, y_mm, z_mm, t)

    def hold(self, duration_s: float) -> PathBuilder:
        self._chunks.append(np.repeat(self.pos[None, :], self._n(duration_s), axis=0))
        return self

    def curve(self, fn: Callable[[NDArray[np.float64]], NDArray[np.float64]],
              duration_s: float) -> PathBuilder:
        """Follow ``fn(t)`` -> [n, 3] for t in (0, duration]; fn(0) should be the current
        position (the curve is offset so that it starts exactly there)."""
        n = self._n(duration_s)
        t = np.arange(1, n + 1) * self.dt_s
        pts = np.asarray(fn(t), np.float64)
        offset = self.pos - np.asarray(fn(np.zeros(1)), np.float64)[0]
        self._chunks.append(pts + offset)
        return self

    def build(self, min_duration_s: float = 0.0) -> FingerPath:
        if self.t_s < min_duration_s:
            self.hold(min_duration_s - self.t_s)
        p = np.concatenate(self._chunks, axis=0)
        return FingerPath(self.dt_s, p[:, 0].copy(), p[:, 1].copy(), p[:, 2].copy())


def _ramp(t: NDArray[np.float64], t_ramp: float) -> NDArray[np.float64]:
    """Phase of a motion that accelerates smoothly to unit rate over ``t_ramp``:
    the integral of a raised-cosine speed ramp."""
    t = np.asarray(t, np.float64)
    inside = t < t_ramp
    ramp_phase = 0.5 * (t - t_ramp / np.pi * np.sin(np.pi * t / t_ramp))
    return np.where(inside, ramp_phase, t - 0.5 * t_ramp)


def _approach(b: PathBuilder, p: TrajectoryParams, x: float, y: float, depth_mm: float
              ) -> None:
    """From wherever the finger is, travel above (x, y) and press down to depth_mm."""
    b.move_at(b.pos[0], b.pos[1], -p.travel_height_mm, p.max_speed_mm_s, p.max_z_speed_mm_s)
    b.move_at(x, y, -p.travel_height_mm, p.max_speed_mm_s, p.max_z_speed_mm_s)
    # Come down and touch: slow at the end (a person places the finger).
    b.move(x, y, depth_mm, max(1.875 * (p.travel_height_mm + depth_mm) / 40.0, 0.5))


def _lift(b: PathBuilder, p: TrajectoryParams, height_mm: float | None = None) -> None:
    h = p.travel_height_mm if height_mm is None else height_mm
    b.move(b.pos[0], b.pos[1], -h, max(1.875 * (h + max(b.pos[2], 0.0)) / 40.0, 0.5))


def _start(p: TrajectoryParams, x: float, y: float) -> PathBuilder:
    b = PathBuilder(x, y - 8.0, -p.far_height_mm)
    b.hold(p.lead_in_s)
    return b


def circle(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """The paper's tele-operation circle: touch, go round at up to ``max_speed``
    (radius 25 mm), pressing 2.5-7.5 mm, lift at the end."""
    r = min(25.0, p.reach_mm[1] - 2.0)
    cx, cy = rng.uniform(-3.0, 3.0), rng.uniform(-2.0, 2.0)
    depth = rng.uniform(4.0, 6.0)
    b = _start(p, cx + r, cy)
    _approach(b, p, cx + r, cy, depth)
    lift_s = 0.9
    run_s = max(seconds - b.t_s - lift_s, 1.0)
    omega = 0.9 * p.max_speed_mm_s / r  # leave room for the depth wobble's speed
    w_dep = 2 * np.pi / rng.uniform(1.5, 2.5)

    def fn(t: NDArray[np.float64]) -> NDArray[np.float64]:
        ph = omega * _ramp(t, 1.0)
        dz = 1.5 * np.sin(w_dep * t)
        return np.column_stack([cx + r * np.cos(ph), cy + r * np.sin(ph), depth + dz])

    b.curve(fn, run_s)
    _lift(b, p)
    return b.build(seconds)


def lissajous(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """A Lissajous-like figure (3:2) over most of the workspace, peak speed ``max_speed``."""
    ax, ay = p.reach_mm[0] - 5.0, p.reach_mm[1] - 4.0
    fx, fy = 3.0, 2.0
    phase = rng.uniform(0.2, 1.2)
    depth = rng.uniform(3.0, 6.0)
    # Peak speed of (ax sin(fx w t), ay sin(fy w t + phase)) is at most w sqrt((ax fx)^2+(ay fy)^2).
    w = 0.95 * p.max_speed_mm_s / np.hypot(ax * fx, ay * fy)

    def xy(ph: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return ax * np.sin(fx * ph), ay * np.sin(fy * ph + phase)

    x0, y0 = xy(np.zeros(1))
    b = _start(p, float(x0[0]), float(y0[0]))
    _approach(b, p, float(x0[0]), float(y0[0]), depth)
    run_s = max(seconds - b.t_s - 0.9, 1.0)
    w_dep = 2 * np.pi / rng.uniform(2.0, 3.0)

    def fn(t: NDArray[np.float64]) -> NDArray[np.float64]:
        x, y = xy(w * _ramp(t, 1.0))
        return np.column_stack([x, y, depth + 1.2 * np.sin(w_dep * t)])

    b.curve(fn, run_s)
    _lift(b, p)
    return b.build(seconds)


def tapping(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """Taps at random places: down to 10-50 mm at up to ``max_z_speed`` and back up to
    a few mm above the fabric (the paper's indentation range is 0-50 mm)."""
    b = _start(p, 0.0, 0.0)
    up = min(p.travel_height_mm, 6.0)
    while b.t_s < seconds - 1.6:
        x = rng.uniform(-p.reach_mm[0] + 8, p.reach_mm[0] - 8)
        y = rng.uniform(-p.reach_mm[1] + 6, p.reach_mm[1] - 6)
        depth = rng.uniform(10.0, 50.0)
        b.move_at(x, y, -up, p.max_speed_mm_s, p.max_z_speed_mm_s, 0.3)
        b.move_at(x, y, depth, p.max_speed_mm_s, p.max_z_speed_mm_s, 0.3)
        b.hold(rng.uniform(0.05, 0.3))
        b.move_at(x, y, -up, p.max_speed_mm_s, p.max_z_speed_mm_s, 0.3)
    return b.build(seconds)


def _random_point(rng: np.random.Generator, p: TrajectoryParams, margin: float = 4.0
                  ) -> tuple[float, float]:
    return (float(rng.uniform(-p.reach_mm[0] + margin, p.reach_mm[0] - margin)),
            float(rng.uniform(-p.reach_mm[1] + margin, p.reach_mm[1] - margin)))


def _point_near(rng: np.random.Generator, p: TrajectoryParams, x_mm: float, y_mm: float,
                radius_mm: float, margin: float = 4.0) -> tuple[float, float]:
    """A random point within ``radius_mm`` of (x, y), inside the reach."""
    r = radius_mm * np.sqrt(rng.uniform(0.1, 1.0))
    a = rng.uniform(0.0, 2.0 * np.pi)
    return (float(np.clip(x_mm + r * np.cos(a), -p.reach_mm[0] + margin, p.reach_mm[0] - margin)),
            float(np.clip(y_mm + r * np.sin(a), -p.reach_mm[1] + margin, p.reach_mm[1] - margin)))


def walk(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """Smooth random free motion: strokes between random points at random speeds (up to
    ``max_speed``), depth varying 2-20 mm, with a lift and re-touch now and then."""
    x, y = _random_point(rng, p)
    b = _start(p, x, y)
    _approach(b, p, x, y, rng.uniform(2.0, 8.0))
    while b.t_s < seconds - 1.2:
        x, y = _random_point(rng, p)
        if rng.uniform() < 0.15:
            _lift(b, p)
            _approach(b, p, x, y, rng.uniform(2.0, 10.0))
            continue
        speed = rng.uniform(0.3, 1.0) * p.max_speed_mm_s
        b.move_at(x, y, rng.uniform(2.0, 20.0), speed, p.max_z_speed_mm_s, 0.3)
        if rng.uniform() < 0.3:
            b.hold(rng.uniform(0.1, 0.5))
    _lift(b, p)
    return b.build(seconds)


def fast(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """Fast straight strokes across the workspace reaching ``max(45, max_speed)`` mm/s,
    pressing lightly (2-6 mm)."""
    v = max(45.0, p.max_speed_mm_s)
    x, y = -p.reach_mm[0] + 5.0, _random_point(rng, p)[1]
    b = _start(p, x, y)
    _approach(b, p, x, y, 3.0)
    sign = 1.0
    while b.t_s < seconds - 1.5:
        x = sign * (p.reach_mm[0] - 5.0)
        y = float(np.clip(b.pos[1] + rng.uniform(-20.0, 20.0),
                          -p.reach_mm[1] + 4, p.reach_mm[1] - 4))
        b.move_at(x, y, rng.uniform(2.0, 6.0), v, p.max_z_speed_mm_s)
        b.hold(rng.uniform(0.05, 0.2))
        sign = -sign
    _lift(b, p)
    return b.build(seconds)


def hover(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """A finger moving 1.5-8 mm above the fabric without touching, then touching,
    stroking, releasing to hover again; in turn until the end."""
    x, y = _random_point(rng, p)
    b = _start(p, x, y)
    b.move_at(x, y, -rng.uniform(4.0, 8.0), p.max_speed_mm_s, 40.0)
    touches = 0
    while b.t_s < seconds - 1.5:
        # Hover about in hops of a second or so (one before the first touch, so that
        # even a short session has contacts to tell apart from the shadow).
        for _ in range(1 if touches == 0 else int(rng.integers(1, 3))):
            x, y = _point_near(rng, p, b.pos[0], b.pos[1], 30.0)
            b.move_at(x, y, -rng.uniform(1.5, 8.0), 0.6 * p.max_speed_mm_s, 20.0, 0.4)
        if touches == 0 or b.t_s < seconds - 2.5:
            b.move(b.pos[0], b.pos[1], rng.uniform(2.0, 6.0), 0.6)   # touch
            x, y = _point_near(rng, p, b.pos[0], b.pos[1], 40.0)
            b.move_at(x, y, rng.uniform(2.0, 6.0), 0.6 * p.max_speed_mm_s, 20.0, 0.4)
            b.move(b.pos[0], b.pos[1], -rng.uniform(2.0, 5.0), 0.6)  # release to hover
            touches += 1
    _lift(b, p)
    return b.build(seconds)


#: The workspace whose calibration points ``presses`` presses (the paper's, the default).
PRESSES_WORKSPACE_MM = (100.0, 70.0)
#: Peak speed of a hop between calibration marks, lifted (a hand moving to the next mark,
#: not a tracked stroke).
HOP_SPEED_MM_S = 250.0


def presses(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """The workspace calibration's presses, round after round: the fabric clear for 2 s,
    then the 9 marked points of the 100 x 70 mm workspace
    (``vision.calibration.default_targets_mm``) pressed in reading order, 6-8 mm deep,
    each held 0.8 s, hopping 3 mm above the fabric between them (< 1 s clear); for
    ``fydpad calibrate workspace`` and the web view's calibration."""
    from vision.calibration import default_targets_mm  # lazy: it loads OpenCV

    targets = default_targets_mm(PRESSES_WORKSPACE_MM)
    b = _start(p, float(targets[0][0]), float(targets[0][1]))
    while b.t_s < seconds:
        b.move_at(b.pos[0], b.pos[1], -p.travel_height_mm, p.max_speed_mm_s,
                  p.max_z_speed_mm_s, 0.5)
        b.hold(1.5)  # the fabric clear: a new round
        for x, y in targets:
            x, y = float(x), float(y)
            # Hops 3 mm above the fabric at a hand's pace between marks (up to
            # HOP_SPEED_MM_S, < 1 s without contact within a round); presses and releases
            # within the finger's z speed.
            b.move_at(x, y, -3.0, HOP_SPEED_MM_S, p.max_z_speed_mm_s, 0.4)
            b.move_at(x, y, rng.uniform(6.0, 8.0), p.max_speed_mm_s, p.max_z_speed_mm_s)
            b.hold(0.8)
            b.move_at(x, y, -3.0, p.max_speed_mm_s, p.max_z_speed_mm_s)
    return b.build(seconds)


#: How far a hand following the indentation protocol misses a mark (mm, radius) and its
#: target depth (fraction): the truth records where and how deep it really pressed.
PROTOCOL_AIM_MM = 2.0
PROTOCOL_DEPTH_SPREAD = 0.1


def protocol(seconds: float, rng: np.random.Generator, p: TrajectoryParams) -> FingerPath:
    """The indentation calibration protocol (``fydpad.indentation_protocol``), its three
    recordings in turn: each starts with the fabric clear for ``CLEAR_S`` (the rest
    distances), then presses its 12 marks in order: down to the mark's depth at up to
    ``max_z_speed`` (at least 0.3 s), held ``HOLD_S``, lifted 3 mm clear and hopped to
    the next mark at a hand's pace (``HOP_SPEED_MM_S``). Each press lands within
    ``PROTOCOL_AIM_MM`` of its mark and within ``PROTOCOL_DEPTH_SPREAD`` of its depth.
    Built whole whatever ``seconds`` (``protocol_duration_s`` says how long it takes)."""
    marks = proto.presses(PRESSES_WORKSPACE_MM)
    b = _start(p, marks[0].x_mm, marks[0].y_mm)
    for rec in range(1, proto.RECORDINGS + 1):
        b.move_at(b.pos[0], b.pos[1], -p.far_height_mm, HOP_SPEED_MM_S, p.max_z_speed_mm_s)
        b.hold(max(proto.CLEAR_S - (p.lead_in_s if rec == 1 else 0.0), 0.0))
        for m in (m for m in marks if m.recording == rec):
            r = PROTOCOL_AIM_MM * np.sqrt(rng.uniform())
            a = rng.uniform(0.0, 2.0 * np.pi)
            x, y = m.x_mm + r * np.cos(a), m.y_mm + r * np.sin(a)
            depth = m.depth_mm * rng.uniform(1 - PROTOCOL_DEPTH_SPREAD, 1 + PROTOCOL_DEPTH_SPREAD)
            b.move_at(x, y, -3.0, HOP_SPEED_MM_S, p.max_z_speed_mm_s, 0.3)
            b.move_at(x, y, depth, p.max_speed_mm_s, p.max_z_speed_mm_s, 0.3)
            b.hold(proto.HOLD_S)
            b.move_at(x, y, -3.0, p.max_speed_mm_s, p.max_z_speed_mm_s, 0.3)
    b.move_at(b.pos[0], b.pos[1], -p.far_height_mm, HOP_SPEED_MM_S, p.max_z_speed_mm_s)
    return b.build(seconds)


def protocol_duration_s(params: TrajectoryParams = TrajectoryParams()) -> float:
    """How long the synthetic hand takes to follow the whole protocol (three recordings)."""
    return protocol(0.0, np.random.default_rng(0), params).duration_s


_BUILDERS: dict[str, Callable[[float, np.random.Generator, TrajectoryParams], FingerPath]] = {
    "circle": circle, "lissajous": lissajous, "tapping": tapping, "walk": walk,
    "fast": fast, "hover": hover, "presses": presses,
    "protocol": protocol,
}


def light_touch(z_mm: NDArray[np.float64], max_mm: float) -> NDArray[np.float64]:
    """Squeeze indentations into (0, max_mm): z -> max (1 - exp(-z / max)); heights stay."""
    return np.where(z_mm > 0, max_mm * (1.0 - np.exp(-np.maximum(z_mm, 0) / max_mm)), z_mm)


def make_path(name: str, seconds: float, rng: np.random.Generator,
              params: TrajectoryParams = TrajectoryParams()) -> FingerPath:
    """The named trajectory, ``seconds`` long (cut or held at the end to fit)."""
    try:
        builder = _BUILDERS[name]
    except KeyError:
        raise ValueError(f"trajectory must be one of {TRAJECTORIES}, got {name!r}") from None
    path = builder(seconds, rng, params)
    n = round(seconds / path.dt_s) + 1
    z = path.z_mm[:n]
    if params.light_max_mm is not None:
        z = light_touch(z, params.light_max_mm)
    return FingerPath(path.dt_s, path.x_mm[:n], path.y_mm[:n], z)


#: What the finger is doing when a recording starts mid-session (:func:`start_time_s`).
START_STATES = ("down_still", "down_moving", "pressing")


def start_time_s(path: FingerPath, state: str, after_s: float = 0.0,
                 lasting_s: float = 0.3) -> float:
    """The first time after ``after_s`` at which the finger is in ``state`` for at least
    ``lasting_s``: ``down_still`` (touching >= 1 mm deep, moving < 2 mm/s),
    ``down_moving`` (touching >= 1 mm deep, moving > 15 mm/s) or ``pressing`` (touching,
    pressing further in at > 10 mm/s). A synthetic recording started there
    (``SynthConfig.start_s``) begins with the finger in that state at frame 0."""
    z = path.z_mm
    speed = path.speed_mm_s()
    z_rate = np.gradient(z, path.dt_s)
    if state == "down_still":
        ok = (z >= 1.0) & (speed < 2.0)
    elif state == "down_moving":
        ok = (z >= 1.0) & (speed > 15.0)
    elif state == "pressing":
        ok = (z > 0.5) & (z_rate > 10.0)
        lasting_s = min(lasting_s, 0.05)
    else:
        raise ValueError(f"state must be one of {START_STATES}, got {state!r}")
    n = max(round(lasting_s / path.dt_s), 1)
    ok[: round(after_s / path.dt_s)] = False
    # Runs of n consecutive samples in the state: the first one's start.
    run = np.convolve(ok.astype(np.int32), np.ones(n, np.int32), mode="valid")
    hits = np.flatnonzero(run == n)
    if not hits.size:
        raise ValueError(f"the finger is never {state.replace('_', ' ')} for {lasting_s} s")
    return float(hits[0] * path.dt_s)
