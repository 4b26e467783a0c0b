"""One object the render loop drives: softness -> motor position, eq. (3) every tick.

Paper Fig. 7: the softness look-up table gives the motor position for the requested
stiffness; a position loop holds it (input_POSITION); the texture's vibration is added
to the PWM (input_VIBRATION); the sum drives the motors (eq. 3).

Station use::

    drive = MotorDrive(motors, table=load_table(path))     # at start
    drive.start()                                         # activate; hold position
    drive.set_stiffness(0.6)                              # when the request changes
    drive.tick(vibration)                                 # every 1 kHz tick
    drive.safe_stop()                                     # stop/fault: never raises

With a board in position mode (:class:`~fydpad.motors.qb.QbMotors` with
``control_mode="position"``) the same calls send position references, the vibration
becoming a position offset (``vibration_rad_per_duty``): see ``docs/motors.md``.
"""

from __future__ import annotations

import math

import numpy as np

from fydpad.motors.base import MotorConfig, MotorError, MotorPair
from fydpad.motors.control import PositionLoop
from fydpad.motors.pwm import PwmComposer, PwmConfig
from fydpad.motors.sim import FabricMotorPlant, SimMotors, indenter_press
from fydpad.softness import (
    SoftnessConfig,
    SoftnessError,
    SoftnessTable,
    characterise_fabric,
    load_table,
)


class MotorDrive:
    """Softness position + eq. (3) for a :class:`MotorPair`, one ``tick`` per render tick."""

    def __init__(self, motors: MotorPair, table: SoftnessTable | None = None,
                 config: MotorConfig | None = None, pwm: PwmConfig | None = None,
                 mode: str = "pwm", vibration_rad_per_duty: float = 0.02,
                 max_theta_rate_rad_s: float = 3.0) -> None:
        if mode not in ("pwm", "position"):
            raise ValueError(f"mode must be 'pwm' or 'position', got {mode!r}")
        self.motors = motors
        self.table = table
        self.config = config if config is not None else MotorConfig()
        self.mode = mode
        c = self.config
        self.composer = PwmComposer(pwm if pwm is not None else PwmConfig(),
                                    c.vibration_sign)
        self.loop = PositionLoop(c.kp_duty_per_rad, c.ki_duty_per_rad_s,
                                 c.kd_duty_s_per_rad, 1.0 / c.rate_hz,
                                 self.composer.position_limit)
        self.vibration_rad_per_duty = vibration_rad_per_duty
        self._dtheta = max_theta_rate_rad_s / c.rate_hz
        self.theta_target_rad = c.rest_theta_rad[0]
        #: The reference actually applied: ramps to the target (no jolt under the finger).
        self.theta_ref_rad = c.rest_theta_rad[0]
        self.requested_k_n_per_mm = math.nan
        self._last_request: tuple[float, bool] | None = None
        self.theta = [math.nan, math.nan]
        self.active = False

    def start(self) -> None:
        """Activate the motors; the reference starts where the rollers are."""
        self.motors.activate()
        self.active = True
        th = self.motors.read_positions_rad()
        self.theta_ref_rad = 0.5 * (th[0] + th[1])
        self.loop.reset()

    def set_stiffness(self, k_n_per_mm: float, strict: bool = False) -> float:
        """Aim at the motor position rendering ``k_n_per_mm`` (the table's inversion;
        clamped with a warning or refused under ``strict``); returns it. NaN means no
        request: the rest position. Cheap to call every tick with an unchanged value."""
        if (k_n_per_mm, strict) == self._last_request or (
                k_n_per_mm != k_n_per_mm and self._last_request is not None
                and self._last_request[0] != self._last_request[0]):
            return self.theta_target_rad  # unchanged: no search, no repeated warning
        if k_n_per_mm != k_n_per_mm:
            # NaN: no stiffness requested (the station's default): the fabric at rest.
            self.set_theta_rad(self.config.rest_theta_rad[0])
            self.requested_k_n_per_mm = math.nan
            self._last_request = (k_n_per_mm, strict)
            return self.theta_target_rad
        if self.table is None:
            raise SoftnessError("no softness table: run 'fydpad softness calibrate' "
                                "(or use the simulated motors)")
        theta = self.table.theta_for(k_n_per_mm, strict=strict)
        self.requested_k_n_per_mm = float(k_n_per_mm)
        self.set_theta_rad(theta)
        self._last_request = (k_n_per_mm, strict)
        return theta

    def set_theta_rad(self, theta_rad: float) -> None:
        """Aim at a motor position directly (characterisation, tests)."""
        self._last_request = None
        c = self.config
        self.theta_target_rad = min(max(float(theta_rad), c.theta_min_rad), c.theta_max_rad)

    def tick(self, vibration: float = 0.0) -> list[float]:
        """One render tick: read encoders, position loop, eq. (3), write. Returns the
        two commanded values (duties, or position references in position mode)."""
        ref = self.theta_ref_rad
        tgt = self.theta_target_rad
        if ref != tgt:
            step = self._dtheta
            ref = tgt if abs(tgt - ref) <= step else ref + (step if tgt > ref else -step)
            self.theta_ref_rad = ref
        comp = self.composer
        if self.mode == "position":
            d = comp.compose(0.0, 0.0, vibration)  # the vibration part, limited + counted
            k = self.vibration_rad_per_duty
            self.theta[0] = ref + k * d[0]
            self.theta[1] = ref + k * d[1]
            self.motors.set_positions_rad(self.theta[0], self.theta[1])
            return self.theta
        th = self.motors.read_positions_rad()
        u = self.loop.update(ref, ref, th[0], th[1])
        d = comp.compose(u[0], u[1], vibration)
        self.motors.set_pwm(d[0], d[1])
        return d

    def safe_stop(self) -> None:
        """Vibration off, motors to rest, power off. Never raises."""
        self.composer.vibration_enabled = False
        self.active = False
        try:
            self.motors.deactivate()
        except Exception:  # the fail-safe path must complete whatever went wrong
            pass

    def stats(self) -> dict:
        out = self.composer.stats()
        out["requested_k_n_per_mm"] = self.requested_k_n_per_mm
        out["theta_target_rad"] = self.theta_target_rad
        return out


def build_drive(motors: MotorConfig | None = None, pwm: PwmConfig | None = None,
                qb=None, softness=None) -> MotorDrive:
    """The drive for a configuration: ``motors.backend`` "sim" (the simulated plant; its
    softness table measured on it by the simulated indenter unless ``softness.table``
    names one) or "qb" (the board at ``qb.port``, in ``qb.control_mode``). Imports the
    backend it needs only (pyserial for "qb")."""
    motors = motors if motors is not None else MotorConfig()
    softness = softness if softness is not None else SoftnessConfig()
    table = load_table(softness.table) if softness.table else None
    if motors.backend == "sim":
        if table is None:
            table = characterise_plant()
        return MotorDrive(SimMotors(config=motors), table, motors, pwm, mode="pwm")
    if motors.backend == "qb":
        from fydpad.motors.qb import QbBoardConfig, QbMotors  # pyserial, for this backend only

        qb = qb if qb is not None else QbBoardConfig()
        return MotorDrive(QbMotors(qb, motors), table, motors, pwm, mode=qb.control_mode)
    raise MotorError(f"motors.backend must be 'sim' or 'qb', got {motors.backend!r}")


def characterise_plant(
    thetas_rad=(0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2), seed: int = 0,
    plant: FabricMotorPlant | None = None,
):
    """The simulated pad's softness table, measured as on the real pad: the motors hold
    each theta (host loop at 1 kHz) while the simulated indenter presses (0.5-10 mm,
    noisy force and depth); k(theta) is fitted from that data, not read from the model.
    Lets ``--motors sim`` render a stiffness without a table file."""
    rng = np.random.default_rng(seed)
    plant = plant if plant is not None else FabricMotorPlant()
    drive = MotorDrive(SimMotors(plant))
    drive.start()

    def hold(ticks: int = 10) -> None:
        for _ in range(ticks):
            drive.tick(0.0)

    theta, depth, force = [], [], []
    for th in thetas_rad:
        drive.set_theta_rad(th)
        hold(800)
        d, f = indenter_press(plant, np.linspace(0.5, 10.0, 20), rng, hold=hold)
        theta += [th] * d.size
        depth += list(d)
        force += list(f)
    drive.safe_stop()
    return characterise_fabric(theta, depth, force)
