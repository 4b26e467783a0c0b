"""The two-motor interface every backend implements (simulated plant, QB board).

Motor k (0 or 1) drives one roller. Convention: a positive angle winds the fabric onto
its roller (stretches it); theta = 0 is the rest position (paper Fig. 6). Duty cycles
are fractions of full PWM in [-1, 1].
"""

from __future__ import annotations

from dataclasses import dataclass
from types import TracebackType
from typing import Protocol, runtime_checkable

from vision.errors import DeviceFault


class MotorError(DeviceFault):
    """A motor backend that cannot do what it was asked (names the device or port)."""

    device = "motors"
    check = "the [motors] and [qb] configuration, the board's cable and its power"


@dataclass(frozen=True)
class MotorConfig:
    """The two motors and how the station drives them (defaults: the paper's pad)."""

    #: "sim" (simulated fabric and motor plant) or "qb" (QB Robotics PSoC board).
    backend: str = "sim"
    #: The rest position of both motors (paper Fig. 6: theta = 0), rad.
    rest_theta_rad: tuple[float, float] = (0.0, 0.0)
    #: Software limits on the position reference (the fabric must not tear), rad.
    theta_min_rad: float = -0.1
    theta_max_rad: float = 1.6
    #: Rate of the render loop that runs eq. 3 (paper III-B: 1 kHz), Hz.
    rate_hz: float = 1000.0
    #: Host position loop (input_POSITION) gains: duty per rad, per rad*s, per rad/s.
    kp_duty_per_rad: float = 4.0
    ki_duty_per_rad_s: float = 40.0
    kd_duty_s_per_rad: float = 0.02
    #: Vibration direction per motor: (+1, -1) moves the fabric along its stretch
    #: direction (one roller winds while the other unwinds), as the paper measured.
    vibration_sign: tuple[float, float] = (1.0, -1.0)
    #: Seconds allowed to reach a new softness position before it is reported late.
    settle_s: float = 0.5


@runtime_checkable
class MotorPair(Protocol):
    """Two motors behind one board. Leaving the context always deactivates them (fail
    safe: vibration off, motors back to rest, then power off), even on an exception."""

    def activate(self) -> None:
        """Power the motors (they hold their current position)."""

    def deactivate(self) -> None:
        """Vibration off, motors back to rest, then unpowered. Must not raise."""

    def set_positions_rad(self, theta0_rad: float, theta1_rad: float) -> None:
        """Position references (board-side position loop)."""

    def set_pwm(self, duty0: float, duty1: float) -> None:
        """PWM duty per motor in [-1, 1] (eq. 3's input_PWM; host-side position loop)."""

    def read_positions_rad(self) -> tuple[float, float]:
        """Encoder positions, rad."""

    def __enter__(self) -> MotorPair: ...

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None: ...
