"""The one fabric model of the FYD-pad: stretch, tension, stiffness, shape under a finger.

An elastic fabric (Superflex HN, paper II-A) is wound between two rollers at
x = +-``roller_x_mm`` (the stretch direction is the workspace's x axis). The same
model serves the synthetic pad (IR distances, load cell, contact size), the
simulated motor plant (tension on the rollers, stiffness, resonance) and later the
chain identification, so the simulated device is one device.

- Stretch: both rollers wind it, ``s = r (theta0 + theta1)``.
- Tension: ``T = T_rest + a s + b s^2`` (the fabric stiffens as it stretches).
- Finger stiffness (paper III-A, F = k(theta) delta): ``k = 4 T / L_eff`` for small
  dents, plus the cubic stiffening of the finger's own dent ``8 a delta^3 / L^2``.
  The defaults put k over the paper's 0.262-1.04 N/mm for theta = 0-1.2 rad per motor.
- Shape under a finger (not a plane, paper II-C): along x the fabric is a string
  pinned at the rollers, straight from each roller to the edge of the finger's contact;
  across y it is free and the sag decays over a length that grows with depth; over the
  contact (a sphere of radius R wrapping ``a = min(R, sqrt(2 R delta))``) it is flat at
  the finger's depth. A plane through three points of it misses the depth under the
  finger by 2.9 mm RMS over 0-50 mm across the workspace (paper: 2.88 mm).
- Vibration: the first mode's frequency rises as sqrt(T).

Pure and small: a frozen dataclass over NumPy, no I/O, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class Fabric:
    """Fabric parameters and laws; lengths in mm, forces in N, angles in rad."""

    roller_radius_mm: float = 10.0
    #: Free length between the rollers (they sit at x = +-span/2 in the workspace frame).
    span_mm: float = 150.0
    #: Effective span of the finger-stiffness law (the 2-D membrane is softer than a
    #: string of the full span): k = 4 T / stiffness_span_mm.
    stiffness_span_mm: float = 150.0
    tension_rest_n: float = 9.8
    axial_n_per_mm: float = 0.9
    axial_n_per_mm2: float = 0.0132
    #: Cubic term from the finger's own dent (0 disables it).
    dent_stiffening: float = 1.0
    resonance_rest_hz: float = 150.0
    resonance_damping: float = 0.12
    #: Moving mass of the fabric per roller, kg.
    mass_kg: float = 0.01
    #: Fingertip modelled as a sphere of this radius for the contact it wraps.
    finger_radius_mm: float = 8.0
    #: Across-stretch (y) decay length of the sag at zero depth, and its growth per mm.
    decay_mm: float = 30.0
    decay_per_mm_depth: float = 0.3

    # ------------------------------------------------------------------ stretch, stiffness

    @property
    def roller_x_mm(self) -> float:
        return 0.5 * self.span_mm

    def stretch_mm(self, theta0_rad: float, theta1_rad: float) -> float:
        """Fabric wound onto both rollers: s = r (theta0 + theta1)."""
        return self.roller_radius_mm * (theta0_rad + theta1_rad)

    def tension_n(self, stretch_mm: float) -> float:
        """T = T_rest + a s + b s^2, never negative (a slack fabric pulls nothing)."""
        s = max(stretch_mm, -self.tension_rest_n / self.axial_n_per_mm)
        return max(self.tension_rest_n + self.axial_n_per_mm * s
                   + self.axial_n_per_mm2 * s * s, 0.0)

    def stiffness_n_per_mm(self, tension_n: float) -> float:
        """Small-indentation stiffness k = dF/d(delta) at delta = 0: 4 T / L_eff."""
        return 4.0 * tension_n / self.stiffness_span_mm

    def stiffness_at_theta(self, theta_rad: float) -> float:
        """k(theta) with both motors at ``theta_rad`` (paper Fig. 6), N/mm."""
        return self.stiffness_n_per_mm(self.tension_n(self.stretch_mm(theta_rad, theta_rad)))

    def force_n(self, indentation_mm: ArrayLike, tension_n: float) -> float | NDArray[np.float64]:
        """F = k delta + 8 a delta^3 / L^2 (the dent's own stretch stiffens it); a float
        for a scalar indentation, an array for an array."""
        d = np.maximum(np.asarray(indentation_mm, np.float64), 0.0)
        cubic = self.dent_stiffening * 8.0 * self.axial_n_per_mm * d ** 3 / self.span_mm ** 2
        f = self.stiffness_n_per_mm(tension_n) * d + cubic
        return float(f) if f.ndim == 0 else f

    def dent_tension_n(self, indentation_mm: float) -> float:
        """Extra tension a finger's dent adds (2 delta^2 / L of extra length)."""
        d = max(indentation_mm, 0.0)
        return self.dent_stiffening * self.axial_n_per_mm * 2.0 * d * d / self.span_mm

    def resonance_hz(self, tension_n: float) -> float:
        """First mode of the stretched fabric, f = f_rest sqrt(T / T_rest)."""
        return self.resonance_rest_hz * math.sqrt(max(tension_n, 1e-6) / self.tension_rest_n)

    # ------------------------------------------------------------------ shape

    def contact_radius_mm(self, indentation_mm: ArrayLike) -> NDArray[np.float64]:
        """Radius of the fabric a spherical fingertip wraps: min(R, sqrt(2 R delta))."""
        d = np.maximum(np.asarray(indentation_mm, np.float64), 0.0)
        r = self.finger_radius_mm
        return np.minimum(r, np.sqrt(2.0 * r * d))

    def deflection_mm(
        self, x_mm: ArrayLike, y_mm: ArrayLike, xf_mm: ArrayLike, yf_mm: ArrayLike,
        depth_mm: ArrayLike,
    ) -> NDArray[np.float64]:
        """Downward deflection at (x, y) with the finger at (xf, yf) pressed ``depth_mm``.

        w = delta * along(x) * across(y): ``along`` is 1 over the contact and falls
        linearly to 0 at each roller (a string pinned there); ``across`` is
        1 / (1 + (gap / ell)^2) with gap the distance beyond the contact in y and
        ell = decay + decay_per_mm * delta. Broadcasts over all arguments.
        """
        x, y, xf, yf, d = np.broadcast_arrays(*(np.asarray(a, np.float64)
                                                for a in (x_mm, y_mm, xf_mm, yf_mm, depth_mm)))
        d = np.maximum(d, 0.0)
        big_l = self.roller_x_mm
        a = self.contact_radius_mm(d)
        left = (x + big_l) / np.maximum(xf - a + big_l, 1e-9)
        right = (big_l - x) / np.maximum(big_l - xf - a, 1e-9)
        along = np.where(x < xf - a, left, np.where(x > xf + a, right, 1.0))
        along = np.clip(along, 0.0, 1.0)
        gap = np.maximum(np.abs(y - yf) - a, 0.0)
        ell = self.decay_mm + self.decay_per_mm_depth * d
        across = 1.0 / (1.0 + (gap / ell) ** 2)
        return d * along * across


#: The motor plant's name for the fabric (``fydpad.motors.sim.default_fabric``).
PlantFabric = Fabric
