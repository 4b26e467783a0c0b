"""The synthetic pad's IR distance sensors and load cell, from the fabric model.

IR (Sharp GP2Y0A41SK0F, paper II-B/II-C): each sensor on the base sees the fabric's
underside; its distance is its rest distance minus the fabric's deflection above it
(:meth:`Fabric.deflection_mm`, not a plane). The sensor measures every ~16.5 ms and
holds its output in between; the output is eq. (1) inverted
(:func:`vision.ir.distance_to_voltage_v`) plus noise; the board samples it with a
10-bit ADC against a 5 V reference (the sensor is a 5 V part; its 0.4-2.75 V output
uses about half the range, 4.9 mV a step).

Load cell (Phidgets CZL616C, 0-780 g): F = k(theta) delta + the dent's cubic
stiffening (:meth:`Fabric.force_n`) + the fabric's viscous damping c d(delta)/dt, plus
noise, clipped at the cell's full scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.fabric import Fabric
from fydpad.synth.trajectory import FingerPath
from vision.ir import distance_to_voltage_v
from vision.recording import DEFAULT_IR_SENSORS_MM

G_M_S2 = 9.80665


@dataclass(frozen=True)
class IRParams:
    sensors_mm: tuple[tuple[float, float], ...] = DEFAULT_IR_SENSORS_MM
    base_to_fabric_mm: float = 100.0
    #: Each sensor's mounting differs from the nominal distance by up to this much.
    mounting_spread_mm: float = 1.5
    #: Where each sensor really is, off its nominal place ``sensors_mm`` (which the
    #: recording's meta.json states), in mm.
    position_error_mm: tuple[tuple[float, float], ...] = ((0.0, 0.0),) * 3
    rate_hz: float = 100.0
    #: The sensor's own measurement period (datasheet: 16.5 +- 3.7 ms).
    update_period_s: float = 0.0165
    noise_v: float = 0.006
    adc_bits: int = 10
    vref_v: float = 5.0


@dataclass(frozen=True)
class ForceParams:
    rate_hz: float = 100.0
    #: Motor position (both rollers) setting the fabric's stretch and so k(theta);
    #: 0 is the motors' rest (the softest fabric, paper Fig. 6).
    theta_rad: float = 0.0
    #: Viscous damping of the fabric, N per mm/s.
    damping_n_s_per_mm: float = 0.004
    noise_n: float = 0.012
    #: Full scale of the CZL616C: 780 g.
    full_scale_n: float = 0.780 * G_M_S2


def ir_volts(path: FingerPath, fabric: Fabric, p: IRParams, rng: np.random.Generator,
             t_s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """IR voltages[n, 3] at the board's sample times ``t_s``, and the sensors' true
    rest distances (mm). The sensors measure at their own period with their own phase;
    the board reads the latest held output."""
    s = np.asarray(p.sensors_mm, np.float64) + np.asarray(p.position_error_mm, np.float64)
    rest_mm = p.base_to_fabric_mm + rng.uniform(-p.mounting_spread_mm, p.mounting_spread_mm, 3)
    out = np.empty((t_s.size, 3))
    for i in range(3):
        # Measurement instants: jittered period, random phase.
        n_meas = int(np.ceil((t_s[-1] + 0.1) / p.update_period_s)) + 2 if t_s.size else 1
        periods = p.update_period_s * (1.0 + rng.uniform(-0.05, 0.05, n_meas))
        t_meas = np.cumsum(periods) - rng.uniform(0, p.update_period_s)
        x, y, z = path.at(t_meas)
        d_mm = rest_mm[i] - fabric.deflection_mm(s[i, 0], s[i, 1], x, y, np.maximum(z, 0.0))
        v_meas = distance_to_voltage_v(d_mm) + rng.normal(0.0, p.noise_v, t_meas.size)
        held = np.clip(np.searchsorted(t_meas, t_s, side="right") - 1, 0, t_meas.size - 1)
        out[:, i] = v_meas[held]
    lsb = p.vref_v / 2 ** p.adc_bits
    return np.clip(np.round(out / lsb), 0, 2 ** p.adc_bits - 1) * lsb, rest_mm


def load_cell_n(path: FingerPath, fabric: Fabric, p: ForceParams, rng: np.random.Generator,
                t_s: NDArray[np.float64]) -> NDArray[np.float64]:
    """Load-cell force in newtons at times ``t_s``, clipped at the cell's full scale."""
    tension = fabric.tension_n(fabric.stretch_mm(p.theta_rad, p.theta_rad))
    d = path.indentation_mm(t_s)
    dt = 1e-3
    rate = (path.indentation_mm(t_s + dt) - path.indentation_mm(t_s - dt)) / (2 * dt)
    f = np.asarray(fabric.force_n(d, tension)) + np.where(d > 0, p.damping_n_s_per_mm * rate,
                                                          0.0)
    f = np.maximum(f, 0.0) + rng.normal(0.0, p.noise_n, t_s.size)
    return np.clip(f, -p.full_scale_n, p.full_scale_n)
