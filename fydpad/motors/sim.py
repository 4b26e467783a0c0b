"""The simulated fabric and motor plant: a digital twin of the pad's actuation.

Two geared DC motors (Maxon REmax class, paper II-A) wind an elastic fabric between
their rollers. Per motor: PWM duty -> armature voltage -> current (back-EMF included,
inductance neglected: L/R is far below a 1 ms tick) -> torque through the gearbox,
against the roller inertia, viscous friction and the fabric's tension on the roller.
The fabric is the one fabric model, :class:`fydpad.fabric.Fabric`: its stretch (both
rollers' winding) sets its tension, the tension sets the stiffness a finger feels
(F = k(theta) * delta, paper III-A) and the frequency of its resonance. The vibration
part of the drive (eq. 3) moves the rollers; the fabric's acceleration along its
stretch direction is the rollers' mean tangential acceleration seen through a
base-excited second-order resonance.

Virtual clock: ``step(n)`` advances n ticks of ``dt_s`` (the render loop's 1 ms) with
fixed sub-steps; nothing here reads a wall clock, so a test or the 1 kHz loop drives it.
:class:`SimMotors` puts the :class:`~fydpad.motors.base.MotorPair` interface on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import TracebackType

import numpy as np

from fydpad.fabric import Fabric
from fydpad.motors.base import MotorConfig, MotorError
from fydpad.motors.control import PositionLoop


def default_fabric() -> Fabric:
    """The plant's fabric: the one fabric model (``fydpad.fabric``), paper defaults."""
    return Fabric()


@dataclass(frozen=True)
class PlantConfig:
    """Motor, gearbox and integration settings (REmax-class motor with a planetary gear)."""

    supply_v: float = 12.0
    resistance_ohm: float = 8.0
    torque_nm_per_a: float = 0.02
    gear_ratio: float = 50.0
    gear_efficiency: float = 0.7
    rotor_inertia_kg_m2: float = 1.0e-6
    roller_inertia_kg_m2: float = 1.0e-4
    friction_nm_s_per_rad: float = 0.005
    #: Absolute magnetic encoder resolution (counts per turn).
    encoder_counts_per_rev: int = 16384
    #: Mechanical stop of each roller (the rest position, paper Fig. 6: theta = 0), rad.
    stop_theta_rad: float = 0.0
    dt_s: float = 0.001
    substeps: int = 10


class FabricMotorPlant:
    """Two motors + fabric, advanced on a virtual clock (``t_s``)."""

    def __init__(self, config: PlantConfig = PlantConfig(),
                 fabric: Fabric | None = None) -> None:
        self.config = config
        self.fabric = fabric if fabric is not None else default_fabric()
        c = config
        n2 = c.gear_ratio * c.gear_ratio
        # Motor side reflected to the roller: inertia and back-EMF damping scale with N^2.
        r_m = self.fabric.roller_radius_mm * 1e-3
        self._inertia = (c.rotor_inertia_kg_m2 * n2 + c.roller_inertia_kg_m2
                         + self.fabric.mass_kg * r_m * r_m)
        self._torque_per_v = c.torque_nm_per_a * c.gear_ratio * c.gear_efficiency \
            / c.resistance_ohm
        self._emf_damping = (c.torque_nm_per_a ** 2) * n2 * c.gear_efficiency \
            / c.resistance_ohm + c.friction_nm_s_per_rad
        self._h = c.dt_s / c.substeps
        self._enc = 2.0 * math.pi / c.encoder_counts_per_rev
        self.reset()

    def reset(self, theta_rad: tuple[float, float] = (0.0, 0.0)) -> None:
        self.t_s = 0.0
        self.theta_rad = [float(theta_rad[0]), float(theta_rad[1])]
        self.omega_rad_s = [0.0, 0.0]
        self.alpha_rad_s2 = [0.0, 0.0]
        self.duty = [0.0, 0.0]
        self.indentation_mm = 0.0
        self._x = 0.0  # fabric mode: displacement relative to the rollers, m
        self._v = 0.0
        self.fabric_accel_m_s2 = 0.0
        self.powered = True
        self._log: np.ndarray | None = None
        self._log_n = 0

    def enable_accel_log(self, capacity: int) -> None:
        """Keep (t_s, fabric_accel_m_s2) at the end of every tick, up to ``capacity``
        ticks (preallocated): the fabric accelerometer of the chain identification."""
        self._log = np.empty((capacity, 2))
        self._log_n = 0

    def accel_log(self) -> np.ndarray:
        """The logged ticks so far, columns t_s and fabric_accel_m_s2 (a copy)."""
        if self._log is None:
            return np.empty((0, 2))
        return self._log[: self._log_n].copy()

    # ------------------------------------------------------------- inputs / outputs

    def set_duty(self, duty0: float, duty1: float) -> None:
        self.duty[0] = min(max(duty0, -1.0), 1.0)
        self.duty[1] = min(max(duty1, -1.0), 1.0)

    def set_indentation_mm(self, indentation_mm: float) -> None:
        """A finger (or indenter) pressing the middle of the fabric this deep."""
        self.indentation_mm = max(float(indentation_mm), 0.0)

    def encoder_rad(self, i: int) -> float:
        """Motor i's encoder reading (quantized)."""
        return round(self.theta_rad[i] / self._enc) * self._enc

    def tension_n(self) -> float:
        f = self.fabric
        return f.tension_n(f.stretch_mm(self.theta_rad[0], self.theta_rad[1])) \
            + f.dent_tension_n(self.indentation_mm)

    def stiffness_n_per_mm(self) -> float:
        """The small-indentation stiffness at the rollers' current positions."""
        f = self.fabric
        return f.stiffness_n_per_mm(f.tension_n(f.stretch_mm(*self.theta_rad)))

    def force_n(self) -> float:
        """The force on the finger at its current indentation."""
        f = self.fabric
        return f.force_n(self.indentation_mm, f.tension_n(f.stretch_mm(*self.theta_rad)))

    # ------------------------------------------------------------------ dynamics

    def step(self, n: int = 1) -> None:
        """Advance n ticks of ``dt_s`` with the current duties (semi-implicit Euler)."""
        f = self.fabric
        h = self._h
        r_m = f.roller_radius_mm * 1e-3
        zeta = f.resonance_damping
        th, om, al = self.theta_rad, self.omega_rad_s, self.alpha_rad_s2
        kv = self._torque_per_v * self.config.supply_v
        stop = self.config.stop_theta_rad
        sub = 0
        for _ in range(n * self.config.substeps):
            tension = self.tension_n()
            load = tension * r_m  # the fabric pulls each roller back (unwinds it)
            for i in (0, 1):
                drive = kv * self.duty[i] if self.powered else 0.0
                acc = (drive - self._emf_damping * om[i] - load) / self._inertia
                om[i] += acc * h
                th[i] += om[i] * h
                if th[i] < stop:
                    # The rollers' mechanical rest: the fabric is mounted pretensioned
                    # against a stop at theta = 0, where an unpowered motor ends up.
                    th[i] = stop
                    if om[i] < 0.0:
                        acc -= om[i] / h
                        om[i] = 0.0
                al[i] = acc
            # Fabric along its stretch direction: rollers' mean tangential acceleration
            # (winding one while unwinding the other moves the fabric) through the
            # base-excited resonance of the stretched fabric.
            base = 0.5 * r_m * (al[0] - al[1])
            w0 = 2.0 * math.pi * f.resonance_hz(tension)
            rel_acc = -2.0 * zeta * w0 * self._v - w0 * w0 * self._x - base
            self._v += rel_acc * h
            self._x += self._v * h
            self.fabric_accel_m_s2 = base + rel_acc
            sub += 1
            if sub == self.config.substeps:
                sub = 0
                self.t_s += self.config.dt_s
                log = self._log
                if log is not None and self._log_n < log.shape[0]:
                    log[self._log_n, 0] = self.t_s
                    log[self._log_n, 1] = self.fabric_accel_m_s2
                    self._log_n += 1


class SimMotors:
    """:class:`~fydpad.motors.base.MotorPair` on the simulated plant.

    Each command (``set_pwm`` or ``set_positions_rad``) advances the plant one tick
    (``step_on_command``), as a real board would have moved by the next 1 kHz tick.
    ``set_positions_rad`` runs a board-side PID like the QB firmware's position mode.
    """

    def __init__(self, plant: FabricMotorPlant | None = None,
                 config: MotorConfig | None = None, step_on_command: bool = True) -> None:
        self.plant = plant if plant is not None else FabricMotorPlant()
        config = config if config is not None else MotorConfig()
        self.config = config
        self.step_on_command = step_on_command
        self.active = False
        self._board_loop = PositionLoop(config.kp_duty_per_rad, config.ki_duty_per_rad_s,
                                        config.kd_duty_s_per_rad, self.plant.config.dt_s, 1.0)
        self.plant.powered = False

    def activate(self) -> None:
        self.active = True
        self.plant.powered = True
        self._board_loop.reset()

    def deactivate(self) -> None:
        """Vibration off, back to rest through the board loop (bounded virtual time), off."""
        try:
            if self.active:
                r0, r1 = self.config.rest_theta_rad
                for _ in range(int(self.config.settle_s / self.plant.config.dt_s)):
                    self.set_positions_rad(r0, r1)
                    if (abs(self.plant.theta_rad[0] - r0) < 0.01
                            and abs(self.plant.theta_rad[1] - r1) < 0.01):
                        break
        finally:
            self.plant.set_duty(0.0, 0.0)
            self.plant.powered = False
            self.active = False

    def _require_active(self) -> None:
        if not self.active:
            raise MotorError("simulated motors: not activated")

    def set_positions_rad(self, theta0_rad: float, theta1_rad: float) -> None:
        self._require_active()
        c = self.config
        r0 = min(max(theta0_rad, c.theta_min_rad), c.theta_max_rad)
        r1 = min(max(theta1_rad, c.theta_min_rad), c.theta_max_rad)
        p = self.plant
        u = self._board_loop.update(r0, r1, p.encoder_rad(0), p.encoder_rad(1))
        p.set_duty(u[0], u[1])
        if self.step_on_command:
            p.step()

    def set_pwm(self, duty0: float, duty1: float) -> None:
        self._require_active()
        self.plant.set_duty(duty0, duty1)
        if self.step_on_command:
            self.plant.step()

    def read_positions_rad(self) -> tuple[float, float]:
        return self.plant.encoder_rad(0), self.plant.encoder_rad(1)

    def __enter__(self) -> SimMotors:
        self.activate()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.deactivate()


def indenter_press(
    plant: FabricMotorPlant, depths_mm: np.ndarray, rng: np.random.Generator,
    force_noise_n: float = 0.02, depth_noise_mm: float = 0.05, hold=None,
) -> tuple[np.ndarray, np.ndarray]:
    """A simulated indenter pressing the plant: at each commanded depth, the force the
    load cell reads and the depth the indenter reports (both with noise). ``hold`` is
    called once per sample to keep the motors' loop running while the indenter presses.
    Returns (indentation_mm, force_n)."""
    depth = np.empty(len(depths_mm))
    force = np.empty(len(depths_mm))
    for j, d in enumerate(depths_mm):
        plant.set_indentation_mm(float(d))
        if hold is not None:
            hold()
        force[j] = plant.force_n() + rng.normal(0.0, force_noise_n)
        depth[j] = float(d) + rng.normal(0.0, depth_noise_mm)
    plant.set_indentation_mm(0.0)
    return depth, force
