"""The render chain the station's 1 kHz process drives: texture vibration, softness
position and eq. (3) on the motors (``fydpad.motors.drive.MotorDrive``)."""

from __future__ import annotations

import math
from dataclasses import replace

from fydpad.chain.live import open_compensator
from fydpad.motors.drive import build_drive
from fydpad.station.outputs import ChannelOutputs
from fydpad.station.spec import RenderSpec
from fydpad.station.texture_source import open_texture, tick_speed


class DriveChain:
    """Texture (when given) + softness + eq. (3) on a motor drive."""

    outputs = ("vibration", "duty0", "duty1", "theta_ref_rad")

    def __init__(self, spec: RenderSpec):
        cfg = spec.config
        motors = replace(cfg.motors, backend=spec.motors, rate_hz=spec.rate_hz)
        self.drive = build_drive(motors, cfg.pwm, cfg.qb, cfg.softness)
        # Every model is loaded now, so switching (the experiment's stimuli) reads no file
        # in the 1 kHz loop: slot 0 is --texture (None: none), then spec.textures.
        self.specs = [spec.texture, *spec.textures]
        # --drive-filter: an error on a --texture of another family (checked before the
        # station starts), ignored on the stimuli of other families.
        self.models = [None if s is None else _TickModel(s, spec.rate_hz, spec.drive_filter,
                                                         lenient=k > 0)
                       for k, s in enumerate(self.specs)]
        if spec.textures:  # the commands log says which model each tick rendered
            self.outputs = (*DriveChain.outputs, "texture")
        self.index = 0
        self.texture = self.models[0]
        self.switches = 0
        self.friction_b_v = math.nan
        #: Each friction model's b as its file gives it (None: not a friction model), for
        #: ``friction_b_v`` = NaN after a live b.
        self._file_b = [m.family.parameters.get("b_v") if m is not None else None
                        for m in self.models]
        #: The one speed input of every family (the centroid's, 10 Hz low-pass per tick).
        self.speed = tick_speed()
        self.dt_s = 1.0 / spec.rate_hz
        #: Failures of ``safe_stop`` (it never raises), one line each.
        self.faults: list[str] = []
        table = self.drive.table
        self._k_lo, self._k_hi = (table.k_range_n_per_mm if table is not None
                                  else (0.0, math.inf))
        self._strict = cfg.softness.strict
        self.compensator = None  # chain compensation: TF inverse, per stiffness
        if spec.compensate is not None:
            self.compensator = open_compensator(spec.compensate, spec.rate_hz)
        self.channels = None  # --channel: the texture's signals to cards and files
        if spec.channels:
            self.channels = ChannelOutputs(list(spec.channels), self.models, spec.rate_hz,
                                           spec.channel_block_ticks)
        self.drive.start()

    def apply_control(self, texture_index: float, friction_b_v: float) -> None:
        """Select the texture model (-1 or out of range: none) and set friction models'
        b (NaN: each file's own b); called by the render loop when the control changes."""
        i = int(texture_index) if texture_index == texture_index else 0
        i = i if 0 <= i < len(self.models) else -1
        if i != self.index:
            self.index = i
            self.texture = self.models[i] if i >= 0 else None
            if self.texture is not None:
                self.texture.reset()  # a fresh start: no filter state of its last use
            # ... and from no speed, not the last one's (it would play for ~50 ms).
            self.speed = tick_speed()
            self.switches += 1
        b_v = float(friction_b_v)
        if not _same(b_v, self.friction_b_v):  # NaN to NaN is no change
            self.friction_b_v = b_v
            for m, file_b in zip(self.models, self._file_b, strict=True):
                if file_b is not None:  # a friction model: b, or NaN: its file's again
                    m.family.set_parameter("b_v", b_v if b_v == b_v else file_b)
            if self.channels is not None:
                self.channels.set_friction_b(b_v)

    def live_stats(self) -> dict:
        """The texture in use, for the station's live figures and the web view."""
        t = self.texture
        return {"index": self.index, "model": self.specs[self.index] if self.index >= 0
                else None, "kind": t.family.kind if t is not None else None,
                "switches": self.switches,
                "friction_b_v": t.family.parameters.get("b_v") if t is not None else None}

    def tick(self, t_s, contact, x_mm, y_mm, speed_mm_s, force_n, vibration_gain,
             stiffness_n_per_mm):
        drive = self.drive
        drive.composer.gain = vibration_gain
        vib = 0.0
        out = None
        tex = self.texture
        if tex is not None:
            if tex.needs_speed:  # a family that reads no speed is spared the estimate
                self.speed.sample(t_s, x_mm, y_mm, contact)
                speed_mm_s = self.speed.tick(self.dt_s)
            out = tex.family.tick(t_s, contact, x_mm, y_mm, speed_mm_s, force_n)
            if tex.vib_i >= 0:
                vib = out[tex.vib_i]
            k = stiffness_n_per_mm
            if tex.ten_i >= 0 and self._k_lo <= k <= self._k_hi:
                # The tension channel scales the softness request, kept within the table
                # (no clamping warning per tick) and rounded (unchanged values are free).
                k = min(max(k * out[tex.ten_i], self._k_lo), self._k_hi)
                stiffness_n_per_mm = round(k, 4)
        drive.set_stiffness(stiffness_n_per_mm, self._strict)
        if self.channels is not None:
            self.channels.tick(t_s, contact, x_mm, y_mm, speed_mm_s, force_n, vibration_gain,
                               self.index, out, vib)
        comp = self.compensator
        if comp is not None:
            comp.select(drive.requested_k_n_per_mm)  # the TF nearest what is rendered
            vib = comp.tick(vib)
        # The per-texture gain is applied by the composer (drive.composer.gain).
        d = drive.tick(vib)
        if len(self.models) > 1:
            return (vib, d[0], d[1], drive.theta_ref_rad, self.index)
        return (vib, d[0], d[1], drive.theta_ref_rad)

    def safe_stop(self) -> None:
        """Motors to rest, then the channels closed, each whatever the other did; what
        failed goes to ``faults`` (one line each) for the render process to report."""
        try:
            self.drive.safe_stop()
        except Exception as exc:
            self.faults.append(f"motors safe stop: {exc}".splitlines()[0])
        if self.channels is not None:  # files keep what was rendered; the card: silence
            self.faults.extend(self.channels.close())

    def stats(self) -> dict:
        """Clipping counts of eq. (3), the softness request and texture limiter resets."""
        out = self.drive.stats()
        if any(m is not None for m in self.models):
            out["texture_limiter_resets"] = sum(m.family.counters().get("limiter_resets", 0)
                                                for m in self.models if m is not None)
        if len(self.models) > 1:
            out["texture_switches"] = self.switches
        if self.compensator is not None:
            out.update(self.compensator.stats())
        if self.channels is not None:
            out["channels"] = self.channels.stats()
        return out


def _same(a: float, b: float) -> bool:
    return a == b or (a != a and b != b)


class _TickModel:
    """A texture family opened for the 1 kHz tick, with where its tick puts each channel."""

    def __init__(self, spec: str, rate_hz: float, drive_filter: bool = False,
                 lenient: bool = False):
        self.family = open_texture(spec, rate_hz, drive_filter=drive_filter, lenient=lenient)
        ch = self.family.tick_channels
        self.needs_speed = "speed_mm_s" in self.family.needs
        # Where the family's tick puts each 1 kHz channel (-1: not rendered).
        self.vib_i = ch.index("vibration") if "vibration" in ch else -1
        self.ten_i = ch.index("tension") if "tension" in ch else -1

    def reset(self) -> None:
        self.family.reset()


def build_render_chain(spec: RenderSpec) -> DriveChain:
    if spec.motors == "none":
        raise ValueError("texture without motors: choose --motors sim or qb")
    if math.isnan(spec.rate_hz) or spec.rate_hz <= 0:
        raise ValueError(f"render rate must be positive, got {spec.rate_hz}")
    return DriveChain(spec)
