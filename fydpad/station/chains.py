"""The render chain the station's 1 kHz process drives: texture vibration, softness
position and eq. (3) on the motors (``fydpad.motors.drive.MotorDrive``)."""

from __future__ import annotations

import math
from dataclasses import replace

from fydpad.station.render import RenderSpec


class DriveChain:
    """Texture (when given) + softness + eq. (3) on a motor drive."""

    outputs = ("vibration", "duty0", "duty1", "theta_ref_rad")

    def __init__(self, spec: RenderSpec):
        from fydpad.motors.drive import build_drive

        cfg = spec.config
        motors = replace(cfg.motors, backend=spec.motors, rate_hz=spec.rate_hz)
        self.drive = build_drive(motors, cfg.pwm, cfg.qb, cfg.softness)
        self.texture = None
        if spec.texture is not None:
            from fydpad.station.texture_source import open_texture

            self.texture = open_texture(spec.texture, spec.rate_hz)
            ch = self.texture.tick_channels
            # Where the family's tick puts each 1 kHz channel (-1: not rendered).
            self._vib_i = ch.index("vibration") if "vibration" in ch else -1
            self._ten_i = ch.index("tension") if "tension" in ch else -1
            table = self.drive.table
            self._k_lo, self._k_hi = (table.k_range_n_per_mm if table is not None
                                      else (0.0, math.inf))
        self._strict = cfg.softness.strict
        self.drive.start()

    def tick(self, t_s, contact, x_mm, y_mm, speed_mm_s, force_n, vibration_gain,
             stiffness_n_per_mm):
        drive = self.drive
        drive.composer.gain = vibration_gain
        vib = 0.0
        if self.texture is not None:
            out = self.texture.tick(t_s, contact, x_mm, y_mm, speed_mm_s, force_n)
            if self._vib_i >= 0:
                vib = out[self._vib_i]
            k = stiffness_n_per_mm
            if self._ten_i >= 0 and self._k_lo <= k <= self._k_hi:
                # The tension channel scales the softness request, kept within the table
                # (no clamping warning per tick) and rounded (unchanged values are free).
                k = min(max(k * out[self._ten_i], self._k_lo), self._k_hi)
                stiffness_n_per_mm = round(k, 4)
        drive.set_stiffness(stiffness_n_per_mm, self._strict)
        # The per-texture gain is applied by the composer (drive.composer.gain).
        d = drive.tick(vib)
        return (vib, d[0], d[1], drive.theta_ref_rad)

    def safe_stop(self) -> None:
        self.drive.safe_stop()

    def stats(self) -> dict:
        """Clipping counts of eq. (3), the softness request and texture limiter resets."""
        out = self.drive.stats()
        if self.texture is not None:
            out["texture_limiter_resets"] = getattr(self.texture, "resets", 0)
        return out


def build_render_chain(spec: RenderSpec) -> DriveChain:
    if spec.motors == "none":
        raise ValueError("texture without motors: choose --motors sim or qb")
    if math.isnan(spec.rate_hz) or spec.rate_hz <= 0:
        raise ValueError(f"render rate must be positive, got {spec.rate_hz}")
    return DriveChain(spec)
