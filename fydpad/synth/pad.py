"""The synthetic pad: a finger trajectory rendered into camera frames, IR and force.

``SyntheticPad(SynthConfig(...))`` draws everything from one seed (a NumPy Generator per
purpose, a fresh one per frame for the sensor noise), so any frame can be rendered on
its own and a session is reproducible. A frame is a pipeline of stages over a float32
grey image of the fabric seen from above (the flipped frame)::

    light (backlight x weave x marks) -> daylight -> hand shadow -> finger shadows
    -> contact (integrated over the exposure) -> room light x auto-exposure
    -> sensor noise, 8 bits -> colour -> JPEG round trip (MJPG) -> camera flip

Each stage is a callable ``stage(img, ctx)`` in :attr:`FrameRenderer.stages`; the effect
flags add theirs, and a caller may insert its own.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from fydpad.fabric import Fabric
from fydpad.synth.effects import (
    AutoExposure,
    Daylight,
    Effects,
    HandShadow,
    PalmRest,
    RoomLight,
)
from fydpad.synth.finger import FingerLook, render_contact, render_shadows
from fydpad.synth.geometry import CameraGeometry
from fydpad.synth.scene import (
    UNEVEN_BACKLIGHT,
    BacklightParams,
    StainParams,
    WeaveParams,
    backlight_field,
    stain_field,
    weave_field,
)
from fydpad.synth.sensors import ForceParams, IRParams, ir_volts, load_cell_n
from fydpad.synth.trajectory import FingerPath, TrajectoryParams, make_path
from vision.mapping import flip_frame
from vision.recording import IMAGE_FLIPS, PadMeta, PadRecordingWriter

#: Seeds of the session's Generators, one per purpose, so adding noise to one part
#: never changes another part's draws.
_SCENE, _PATH, _IR, _FORCE, _LIGHT, _FRAME = range(6)


@dataclass(frozen=True)
class SynthConfig:
    """Everything a synthetic session depends on; defaults are the paper's pad."""

    trajectory: str = "circle"
    seconds: float = 10.0
    seed: int = 0
    #: Where in the trajectory the recording starts (s): > 0 starts it mid-session,
    #: e.g. with the finger already down, still or moving, or pressing.
    start_s: float = 0.0
    effects: Effects = field(default_factory=Effects)
    image_flip: str = "horizontal"
    fps: float = 30.0
    frame_size: tuple[int, int] = (640, 480)
    roi_px: tuple[int, int, int, int] = (24, 22, 592, 414)
    workspace_mm: tuple[float, float] = (100.0, 70.0)
    #: Exposure time; None: 1/60 s, or 1/30 s with the ``fast`` effect.
    exposure_s: float | None = None
    #: Largest motion of the contact between two sub-frames of the exposure, pixels.
    blur_step_px: float = 1.0
    #: The webcam's MJPG compression (a JPEG round trip per frame); None: off.
    mjpg_quality: int | None = 80
    #: Sensor noise: read noise and shot-noise gain in grey levels (var = r^2 + g I).
    read_noise: float = 1.2
    shot_gain: float = 0.02
    #: Colour of the light (B, G, R gains; their grey mix is 1).
    tint_bgr: tuple[float, float, float] = (0.93, 1.0, 1.03)
    backlight: BacklightParams = field(default_factory=BacklightParams)
    weave: WeaveParams = field(default_factory=WeaveParams)
    stains: StainParams = field(default_factory=StainParams)
    look: FingerLook = field(default_factory=FingerLook)
    fabric: Fabric = field(default_factory=Fabric)
    ir: IRParams = field(default_factory=IRParams)
    force: ForceParams = field(default_factory=ForceParams)
    path: TrajectoryParams = field(default_factory=TrajectoryParams)

    def __post_init__(self) -> None:
        if self.image_flip not in IMAGE_FLIPS:
            raise ValueError(f"image_flip must be one of {IMAGE_FLIPS}, got {self.image_flip!r}")
        if not self.seconds > 0:
            raise ValueError(f"seconds must be positive, got {self.seconds}")
        if not self.fps > 0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        if not self.start_s >= 0:
            raise ValueError(f"start_s must be >= 0, got {self.start_s}")

    @property
    def exposure(self) -> float:
        if self.exposure_s is not None:
            return self.exposure_s
        return 1.0 / 30.0 if self.effects.fast else 1.0 / 60.0

    @property
    def frame_count(self) -> int:
        return math.floor(self.seconds * self.fps + 1e-9)


@dataclass(frozen=True)
class FrameTruth:
    """Ground truth of one frame: the finger at the middle of its exposure."""

    frame: int
    t_s: float
    contact: bool
    x_mm: float
    y_mm: float
    #: Indentation (0 without contact) and the signed z (negative: height above).
    indentation_mm: float
    z_mm: float


@dataclass
class FrameContext:
    """What the stages of one frame share."""

    k: int
    t_s: float
    #: The finger at sub-frame instants over the exposure, and at its middle.
    xs: NDArray[np.float64]
    ys: NDArray[np.float64]
    zs: NDArray[np.float64]
    x_mm: float
    y_mm: float
    z_mm: float
    rng: np.random.Generator
    gain: float = 1.0
    out: NDArray[np.uint8] | None = None
    extra: dict[str, Any] = field(default_factory=dict)


Stage = Callable[[NDArray[np.float32], FrameContext], None]


def _effective(cfg: SynthConfig) -> SynthConfig:
    """Apply the effects that change the trajectory, the look or the light."""
    e = cfg.effects
    path, look, backlight = cfg.path, cfg.look, cfg.backlight
    if e.fast:
        path = replace(path, max_speed_mm_s=max(path.max_speed_mm_s, 45.0))
    if e.hover:
        # Between contacts the finger stays low, and a lamp right above gives a dark shadow.
        path = replace(path, travel_height_mm=min(path.travel_height_mm, 3.0))
        look = replace(look, tip_shadow=0.5, tip_height_mm=5.0)
    if e.light_touch:
        path = replace(path, light_max_mm=1.5)
        look = replace(look, contact_darkness=0.25, onset_mm=0.4)
    if e.uneven_light:
        backlight = UNEVEN_BACKLIGHT
    return replace(cfg, path=path, look=look, backlight=backlight)


class FrameRenderer:
    """Renders frame k of a session as a pipeline of stages (see the module doc)."""

    def __init__(self, cfg: SynthConfig, path: FingerPath):
        self.cfg = cfg
        self.path = path
        self.geom = CameraGeometry(cfg.frame_size, cfg.roi_px, cfg.workspace_mm)
        scene_rng = np.random.default_rng((cfg.seed, _SCENE))
        light_rng = np.random.default_rng((cfg.seed, _LIGHT))
        # The still parts of the picture, once.
        still = backlight_field(self.geom, cfg.backlight, scene_rng)
        still *= weave_field(self.geom, cfg.weave, scene_rng)
        if cfg.effects.stains:
            still *= stain_field(self.geom, cfg.stains, scene_rng)
        self.still = still
        lut = np.arange(256, dtype=np.float32)
        self._luts = [np.clip(np.round(lut * g), 0, 255).astype(np.uint8) for g in cfg.tint_bgr]
        self.stages: list[tuple[str, Stage]] = []
        e = cfg.effects
        self.daylight: Daylight | None = None
        if e.daylight:
            daylight = self.daylight = Daylight(light_rng, self.geom)
            self.stages.append(("daylight", lambda img, c: img.__imul__(daylight.field(c.t_s))))
        if e.hand_shadow:
            hand = HandShadow(light_rng, self.geom)
            self.stages.append(("hand_shadow",
                                lambda img, c: hand.apply(img, c.x_mm, c.y_mm, c.z_mm)))
        if e.palm_rest:
            palm = PalmRest(light_rng, self.geom)
            self.stages.append(("palm_rest", lambda img, c: palm.apply(img, c.t_s)))
        self.stages.append(("finger_shadows", self._shadows))
        self.stages.append(("contact", self._contact))
        if e.room_light:
            room = RoomLight(light_rng, cfg.seconds, cfg.exposure, start_s=cfg.path.lead_in_s)
            self.room_light: RoomLight | None = room
            self.stages.append(("room_light", lambda img, c: _gain(c, room.gain(c.t_s))))
        else:
            self.room_light = None
        self.auto_exposure: AutoExposure | None = None
        if e.auto_exposure:
            ae = self.auto_exposure = AutoExposure(light_rng, room=self.room_light)
            self.stages.append(("auto_exposure", lambda img, c: _gain(c, ae.gain(c.t_s))))
        self.stages.append(("sensor", self._sensor))
        if cfg.mjpg_quality is not None:
            self.stages.append(("mjpg", self._mjpg))
        self.stages.append(("flip", self._flip))

    # ------------------------------------------------------------------ stages

    def _shadows(self, img: NDArray[np.float32], c: FrameContext) -> None:
        render_shadows(img, self.geom, self.cfg.look, c.x_mm, c.y_mm, c.z_mm)

    def _contact(self, img: NDArray[np.float32], c: FrameContext) -> None:
        render_contact(img, self.geom, self.cfg.look, self.cfg.fabric, c.xs, c.ys, c.zs)

    def _sensor(self, img: NDArray[np.float32], c: FrameContext) -> None:
        """Global gain, shot + read noise (var = r^2 + g I), 8-bit quantisation, colour."""
        if c.gain != 1.0:
            img *= np.float32(c.gain)
        sigma = np.sqrt(np.float32(self.cfg.read_noise ** 2) + np.float32(self.cfg.shot_gain)
                        * np.maximum(img, 0.0))
        img += sigma * c.rng.standard_normal(img.shape, dtype=np.float32)
        grey = np.clip(img + 0.5, 0, 255).astype(np.uint8)
        c.out = cv2.merge([cv2.LUT(grey, lut) for lut in self._luts])

    def _mjpg(self, img: NDArray[np.float32], c: FrameContext) -> None:
        _ok, buf = cv2.imencode(".jpg", c.out, [cv2.IMWRITE_JPEG_QUALITY, self.cfg.mjpg_quality])
        c.out = cv2.imdecode(buf, cv2.IMREAD_COLOR)

    def _flip(self, img: NDArray[np.float32], c: FrameContext) -> None:
        # The camera looks up at the fabric: its raw frame is the flipped view (the flip
        # is its own inverse).
        c.out = flip_frame(c.out, self.cfg.image_flip)

    # ------------------------------------------------------------------ frames

    def context(self, k: int) -> FrameContext:
        """Finger samples over frame k's exposure (centred on t = k / fps)."""
        cfg = self.cfg
        t = cfg.start_s + k / cfg.fps  # on the trajectory's clock
        e = cfg.exposure
        x, y, z = self.path.at(np.array([t - e / 2, t, t + e / 2]))
        sx, sy = self.geom.px_per_mm
        # Enough sub-frames that the contact moves at most blur_step_px between two,
        # bounding the travel by the chord (the paths are smooth at this scale).
        travel_px = max(abs(x[2] - x[0]) * sx, abs(y[2] - y[0]) * sy, abs(z[2] - z[0]) * sx)
        n = int(np.clip(np.ceil(travel_px / cfg.blur_step_px), 1, 48))
        ts = t - e / 2 + (np.arange(n) + 0.5) * (e / n)
        xs, ys, zs = self.path.at(ts)
        rng = np.random.default_rng((cfg.seed, _FRAME, k))
        return FrameContext(k, k / cfg.fps, xs, ys, zs, float(x[1]), float(y[1]), float(z[1]), rng)

    def render(self, k: int) -> NDArray[np.uint8]:
        """Raw camera frame k (BGR, as the camera gives it: flipped per ``image_flip``)."""
        c = self.context(k)
        img = self.still.copy()
        for _, stage in self.stages:
            stage(img, c)
        assert c.out is not None
        return c.out


def _gain(c: FrameContext, g: float) -> None:
    c.gain *= g


class SyntheticPad:
    """A synthetic pad session: frames, IR, force and truth from one configuration."""

    def __init__(self, cfg: SynthConfig | None = None):
        cfg = cfg if cfg is not None else SynthConfig()
        self.requested = cfg
        self.cfg = _effective(cfg)
        self.path = make_path(self.cfg.trajectory, self.cfg.start_s + self.cfg.seconds,
                              np.random.default_rng((cfg.seed, _PATH)), self.cfg.path)
        self.renderer = FrameRenderer(self.cfg, self.path)
        self._ir: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self.ir_rest_mm: NDArray[np.float64] | None = None

    @property
    def frame_count(self) -> int:
        return self.cfg.frame_count

    def truth(self, k: int) -> FrameTruth:
        t = k / self.cfg.fps
        x, y, z = (float(a) for a in self.path.at(self.cfg.start_s + t))
        return FrameTruth(k, t, z > 0, x, y, max(z, 0.0), z)

    def straddles_contact(self, k: int) -> bool:
        """True when the finger touched the fabric for part, not all, of frame k's
        exposure (at the sub-frame instants the frame is rendered from): the camera saw a
        touch-down or a release, so either answer about contact is right for that frame."""
        zs = self.renderer.context(k).zs
        return bool(np.any(zs > 0) and not np.all(zs > 0))

    def frame(self, k: int) -> NDArray[np.uint8]:
        return self.renderer.render(k)

    def frames(self) -> Iterator[tuple[NDArray[np.uint8], FrameTruth]]:
        """Yield (raw BGR frame, truth) for every frame of the session, in order."""
        for k in range(self.frame_count):
            yield self.frame(k), self.truth(k)

    def ir(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(t_s, volts[n, 3]) of the IR board over the session."""
        if self._ir is None:
            p = self.cfg.ir
            t = np.arange(math.floor(self.cfg.seconds * p.rate_hz + 1e-9)) / p.rate_hz
            v, rest = ir_volts(self.path, self.cfg.fabric, p,
                               np.random.default_rng((self.cfg.seed, _IR)),
                               t + self.cfg.start_s)
            self._ir, self.ir_rest_mm = (t, v), rest
        return self._ir

    def force(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(t_s, force_n) of the load cell over the session."""
        p = self.cfg.force
        t = np.arange(math.floor(self.cfg.seconds * p.rate_hz + 1e-9)) / p.rate_hz
        return t, load_cell_n(self.path, self.cfg.fabric, p,
                              np.random.default_rng((self.cfg.seed, _FORCE)), t + self.cfg.start_s)

    def meta(self) -> PadMeta:
        cfg = self.cfg
        self.ir()
        synthetic = {
            "generator": "fydpad synth",
            "trajectory": cfg.trajectory,
            "seconds": cfg.seconds,
            "start_s": cfg.start_s,
            "seed": cfg.seed,
            "effects": cfg.effects.names(),
            "exposure_s": cfg.exposure,
            "mjpg_quality": cfg.mjpg_quality,
            "motor_theta_rad": cfg.force.theta_rad,
            "stiffness_n_per_mm": cfg.fabric.stiffness_at_theta(cfg.force.theta_rad),
            "ir_rest_mm": [round(float(v), 4) for v in self.ir_rest_mm],  # type: ignore[union-attr]
            "fabric": asdict(cfg.fabric),
        }
        return PadMeta(
            roi_px=cfg.roi_px, workspace_mm=cfg.workspace_mm, fps=cfg.fps,
            frame_size=cfg.frame_size, image_flip=cfg.image_flip,
            ir_sensors_mm=cfg.ir.sensors_mm, base_to_fabric_mm=cfg.ir.base_to_fabric_mm,
            extra={"synthetic": synthetic},
        )

    def write(self, outdir: str | Path, video_name: str = "video.avi",
              progress: Callable[[Iterator[Any], int], Iterator[Any]] | None = None) -> Path:
        """Write the session as a pad session recording (docs/recording_format.md)."""
        outdir = Path(outdir)
        with PadRecordingWriter(outdir, self.meta(), video_name=video_name) as w:
            t_ir, v = self.ir()
            for t, (v0, v1, v2) in zip(t_ir, v, strict=True):
                w.write_ir(float(t), float(v0), float(v1), float(v2))
            for t, f in zip(*self.force(), strict=True):
                w.write_force(float(t), float(f))
            it: Iterator[Any] = self.frames()
            if progress is not None:
                it = progress(it, self.frame_count)
            for frame, tr in it:
                w.write_frame(frame)
                w.write_truth(tr.t_s, tr.frame, tr.contact, tr.x_mm, tr.y_mm, tr.indentation_mm)
        return outdir
