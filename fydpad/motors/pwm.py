"""Eq. (3): input_PWM = input_POSITION + input_VIBRATION, per motor, at 1 kHz.

The position part keeps the fabric at the stretch that renders the requested stiffness
(paper III-A, Fig. 7); the vibration part renders texture (III-B). The duty range is
split: the position part may use at most ``duty_max - vibration_headroom`` and the
vibration part at most ``vibration_headroom``, so their sum never exceeds ``duty_max``:
vibration can never push the position loop into saturation (which would lose the
stretch, hence the stiffness, while a texture plays). Each part is clipped to its share
and every clip is counted, so a session reports how often either hit its limit.

``compose`` is the per-tick call: scalars in, the two duties written into the
preallocated ``duty`` list, nothing allocated beyond Python floats.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PwmConfig:
    """Duty limits of eq. (3) (fractions of full PWM)."""

    #: The board's full scale; duties are clipped to +-duty_max.
    duty_max: float = 1.0
    #: Share of duty_max reserved to the vibration; the position part gets the rest.
    vibration_headroom: float = 0.3
    #: Duty per unit of the texture signal (the synthesized vibration, m/s^2), before
    #: the per-texture gain (the paper's gain 1). A device constant, not a texture's:
    #: 0.05 puts a rough texture's ~2 m/s^2 RMS at a third of the 0.3 headroom, so its
    #: peaks are rarely clipped. The actuator-chain identification will calibrate it.
    vibration_duty_per_unit: float = 0.05

    def __post_init__(self) -> None:
        if not 0.0 < self.duty_max <= 1.0:
            raise ValueError(f"duty_max must be in (0, 1], got {self.duty_max}")
        if not 0.0 <= self.vibration_headroom < self.duty_max:
            raise ValueError("vibration_headroom must be in [0, duty_max)")


class PwmComposer:
    """Eq. (3) for two motors with headroom, a per-texture gain and clip counters."""

    def __init__(self, config: PwmConfig = PwmConfig(),
                 vibration_sign: tuple[float, float] = (1.0, -1.0)) -> None:
        self.config = config
        self.position_limit = config.duty_max - config.vibration_headroom
        self.vibration_limit = config.vibration_headroom
        self.sign0, self.sign1 = float(vibration_sign[0]), float(vibration_sign[1])
        #: Per-texture vibration gain (paper III-B: 1 by default, user-adjustable).
        self.gain = 1.0
        #: Vibration on/off (off: eq. 3 reduces to the position part; the fail-safe).
        self.vibration_enabled = True
        #: The last tick's duties, written in place.
        self.duty = [0.0, 0.0]
        self.ticks = 0
        self.position_clips = 0
        self.vibration_clips = 0

    def compose(self, position0: float, position1: float, vibration: float) -> list[float]:
        """One tick: the two duties from the position loop outputs and the texture signal
        (one value, applied to each motor with its ``vibration_sign``)."""
        plim = self.position_limit
        vlim = self.vibration_limit
        self.ticks += 1
        if position0 > plim:
            position0 = plim
            self.position_clips += 1
        elif position0 < -plim:
            position0 = -plim
            self.position_clips += 1
        if position1 > plim:
            position1 = plim
            self.position_clips += 1
        elif position1 < -plim:
            position1 = -plim
            self.position_clips += 1
        v = vibration * self.gain * self.config.vibration_duty_per_unit \
            if self.vibration_enabled else 0.0
        if v > vlim:
            v = vlim
            self.vibration_clips += 1
        elif v < -vlim:
            v = -vlim
            self.vibration_clips += 1
        d = self.duty
        d[0] = position0 + self.sign0 * v
        d[1] = position1 + self.sign1 * v
        return d

    def stats(self) -> dict:
        """Clip counts and shares for the session report."""
        n = max(self.ticks, 1)
        return {
            "ticks": self.ticks,
            "position_clips": self.position_clips,
            "vibration_clips": self.vibration_clips,
            "position_clip_pct": 100.0 * self.position_clips / (2 * n),
            "vibration_clip_pct": 100.0 * self.vibration_clips / n,
            "gain": self.gain,
        }

    def reset_stats(self) -> None:
        self.ticks = self.position_clips = self.vibration_clips = 0
