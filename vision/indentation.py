"""Finger indentation from the three IR distance sensors: eq. (1), the plane of eq. (2),
and a correction fitted beyond the plane (paper II-C).

Sign convention. Each sensor on the base measures the distance z_i from the base *up*
to the fabric above it. A finger pushes the fabric *down*, towards the base, so z_i
shrinks: ``e_i = z_i - zbar_i`` (zbar_i the rest distance) is negative when pressing.
The plane through the three points (x_i, y_i, e_i) evaluated at the contact centroid
gives eq. (2)'s delta, also negative when pressing; the indentation (positive down,
docs/recording_format.md) is ``-delta``.

Eq. (2) is the plane for the paper's sensor positions (-22, -3), (0, 27), (22, -3) mm:
solved for delta it is the barycentric interpolation of e_0, e_1, e_2. This module
builds the same plane for any three non-collinear positions (``plane_weights``);
``paper_eq2_delta_mm`` is eq. (2) as printed, kept for the test that they agree.

The flat region of eq. (1). The fit's slope falls from about -80 mm/V at the rest
distance (1.3 V, 100 mm) to about -2 mm/V at 2.3-2.4 V: the whole 2.2-2.5 V band maps
onto 52.4-53.7 mm. One step of a 10-bit, 5 V ADC (4.9 mV) is 0.39 mm at rest but
0.01 mm there; that apparent precision is the fit's artefact, not the sensor's (the
datasheet curve still falls about 0.4 V/cm there): distances the sensor tells apart
over several mm all read as about 53 mm. Readings in the band are valid but flagged
``IRFlag.FLAT_REGION``; see docs/indentation.md for the table.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.config import PAPER_SENSORS_MM, IRConfig
from vision.errors import UserError
from vision.ir import PAPER_POLY_CM, SENSOR_PERIOD_S, VALID_VOLTAGE_RANGE_V

#: Voltages where eq. (1) is nearly flat (slope under about 13 mm/V): low resolution.
FLAT_REGION_V: tuple[float, float] = (2.2, 2.5)


class IRFlag(enum.IntFlag):
    """Per-sample quality flags; any of ``INVALID`` makes the indentation NaN."""

    OK = 0
    INVALID_V0 = 1  # sensor 0 voltage NaN or outside its valid range: not extrapolated
    INVALID_V1 = 2
    INVALID_V2 = 4
    FLAT_REGION = 8  # a voltage in eq. (1)'s flat band: valid, but distance poorly resolved
    NO_CONTACT = 16  # no finger: indentation is 0 by the recording format
    NO_CENTROID = 32  # contact without a finite (x, y): the plane cannot be evaluated
    NO_IR = 64  # no IR sample close enough in time
    EXTRAPOLATED = 128  # centroid outside the sensor triangle: the plane is extrapolated


INVALID = (IRFlag.INVALID_V0 | IRFlag.INVALID_V1 | IRFlag.INVALID_V2 | IRFlag.NO_CENTROID
           | IRFlag.NO_IR)
_SENSOR_INVALID = (IRFlag.INVALID_V0, IRFlag.INVALID_V1, IRFlag.INVALID_V2)


# --------------------------------------------------------------------------- eq. (1)


def sensor_distances_mm(
    volts: ArrayLike,
    poly_cm: Sequence[Sequence[float]] = (PAPER_POLY_CM,) * 3,
    valid_range_v: Sequence[tuple[float, float]] = (VALID_VOLTAGE_RANGE_V,) * 3,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Eq. (1) per sensor: ``volts[n, 3]`` -> (distances_mm[n, 3], flags[n]).

    Out-of-range or NaN voltages give NaN and an ``INVALID_Vi`` flag; nothing is
    extrapolated. Voltages in the flat band are flagged ``FLAT_REGION``.
    """
    v = np.atleast_2d(np.asarray(volts, dtype=np.float64))
    if v.shape[-1] != 3:
        raise ValueError(f"expected volts of shape (n, 3), got {v.shape}")
    d = np.empty_like(v)
    flags = np.zeros(v.shape[0], dtype=np.int64)
    for i in range(3):
        lo, hi = valid_range_v[i]
        ok = (v[:, i] >= lo) & (v[:, i] <= hi)  # False for NaN too
        d[:, i] = np.where(ok, np.polyval(np.asarray(poly_cm[i], np.float64), v[:, i]) * 10.0,
                           np.nan)
        flags |= np.where(ok, 0, int(_SENSOR_INVALID[i]))
        flat = ok & (v[:, i] >= FLAT_REGION_V[0]) & (v[:, i] <= FLAT_REGION_V[1])
        flags |= np.where(flat, int(IRFlag.FLAT_REGION), 0)
    return d, flags


def distance_resolution_mm(
    voltage_v: ArrayLike, poly_cm: Sequence[float] = PAPER_POLY_CM,
    adc_bits: int = 10, vref_v: float = 5.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Local slope of eq. (1) in mm/V and the distance one ADC step spans, in mm."""
    slope = np.polyval(np.polyder(np.asarray(poly_cm, np.float64)), np.asarray(voltage_v)) * 10
    return slope, np.abs(slope) * vref_v / 2**adc_bits


# --------------------------------------------------------------------------- eq. (2)


def plane_weights(
    sensors_mm: Sequence[Sequence[float]], x_mm: ArrayLike, y_mm: ArrayLike,
) -> NDArray[np.float64]:
    """Barycentric weights w[n, 3] of (x, y) for the sensor triangle.

    The plane through (x_i, y_i, e_i) takes the value ``sum_i w_i e_i`` at (x, y);
    the weights sum to 1 and are all in [0, 1] inside the triangle.
    """
    s = np.asarray(sensors_mm, dtype=np.float64)
    m = np.vstack([s[:, 0], s[:, 1], np.ones(3)])  # columns: sensors
    area2 = np.linalg.det(m)
    scale = max(float(np.ptp(s[:, 0])), float(np.ptp(s[:, 1])), 1e-12)
    if abs(area2) < 1e-6 * scale**2:
        raise ValueError(f"IR sensor positions {s.tolist()} are collinear: no plane through them")
    rhs = np.vstack([np.ravel(np.asarray(x_mm, np.float64)),
                     np.ravel(np.asarray(y_mm, np.float64)),
                     np.ones(np.size(x_mm))])
    return np.linalg.solve(m, rhs).T


def plane_delta_mm(
    e_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike,
    sensors_mm: Sequence[Sequence[float]] = PAPER_SENSORS_MM,
) -> NDArray[np.float64]:
    """delta of eq. (2), generalised: the plane through (x_i, y_i, e_i) at (x, y)."""
    e = np.atleast_2d(np.asarray(e_mm, dtype=np.float64))
    return np.sum(plane_weights(sensors_mm, x_mm, y_mm) * e, axis=1)


def paper_eq2_delta_mm(
    e0: ArrayLike, e1: ArrayLike, e2: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike,
) -> NDArray[np.float64]:
    """Eq. (2) as printed, solved for delta:
    ``e1(44y + 132) - 1320 delta - e0(30x + 22y - 594) + e2(30x - 22y + 594) = 0``."""
    e0, e1, e2, x, y = (np.asarray(a, np.float64) for a in (e0, e1, e2, x_mm, y_mm))
    return (e1 * (44 * y + 132) - e0 * (30 * x + 22 * y - 594) + e2 * (30 * x - 22 * y + 594)) \
        / 1320.0


# --------------------------------------------------------------------------- baselines


def estimate_baseline_mm(
    distances_mm: ArrayLike, no_contact: ArrayLike, min_samples: int = 5,
) -> NDArray[np.float64]:
    """Rest distance per sensor from its valid samples taken without contact: the
    interquartile mean (sorted, the lowest and highest quarter dropped, the rest
    averaged).

    Robust like the median (the odd spike of these noisy sensors falls outside the
    quartiles), but where the median sticks to one of the 10-bit ADC's levels (0.38 mm
    apart at rest), the mean of the central half averages the noise across levels
    and resolves the rest distance finer than one step. NaN for a sensor with fewer
    than ``min_samples`` such samples.
    """
    d = np.atleast_2d(np.asarray(distances_mm, dtype=np.float64))
    free = np.asarray(no_contact, dtype=bool)
    out = np.full(3, np.nan)
    for i in range(3):
        col = d[free, i]
        col = np.sort(col[np.isfinite(col)])
        if col.size >= min_samples:
            cut = col.size // 4  # by rank, so ties at an ADC level are split fairly
            out[i] = float(np.mean(col[cut:col.size - cut]))
    return out


def resolve_baseline_mm(
    configured_mm: Sequence[float] | None,
    estimated_mm: ArrayLike | None,
    base_to_fabric_mm: float,
) -> NDArray[np.float64]:
    """docs/recording_format.md's rule: the given ``baseline_mm``; where absent, the estimate
    from samples without contact; where there is none, ``base_to_fabric_mm``."""
    if configured_mm is not None:
        return np.asarray(configured_mm, dtype=np.float64).copy()
    out = np.full(3, float(base_to_fabric_mm))
    if estimated_mm is not None:
        est = np.asarray(estimated_mm, dtype=np.float64)
        out = np.where(np.isfinite(est), est, out)  # per sensor
    return out


# --------------------------------------------------------------------------- correction


@dataclass(frozen=True)
class SagCorrection:
    """The depth from how the fabric sags between each sensor and the finger (the
    correction beyond the plane): each sensor's own deflection e_i (positive down)
    weighted by a polynomial of the centroid, u = x/50, v = y/50,
    ``depth = sum_a sum_i sum_jk c e_i^a / 50^(a-1) u^j v^k``, a = 1..``depth_degree``,
    j + k <= ``xy_degree`` (what ``fydpad calibrate indentation`` fits). Every term
    vanishes with no deflection (no indentation stays no indentation).

    The plane of eq. (2) is the case of weights linear in (x, y) (the barycentric ones).
    A real fabric is not a plane: it sags towards the finger, so the sensors (22-30 mm
    away) see less than the finger's depth, by a factor that depends on where the finger
    is and, as the fabric wraps the finger, on the depth. Free weights learn how the
    fabric really sags between each sensor and the finger, sensors mounted off their
    nominal places included, so a fit on presses holds for strokes elsewhere at other
    depths. Fitted by ridge least squares, shrunk towards the plane.
    """

    coef: tuple[float, ...]
    xy_degree: int = 3
    depth_degree: int = 2

    def __post_init__(self) -> None:
        n = self.n_coef(self.xy_degree, self.depth_degree)
        if len(self.coef) != n:
            raise ValueError(f"correction: expected {n} coefficients for xy degree "
                             f"{self.xy_degree} and depth degree {self.depth_degree}, "
                             f"got {len(self.coef)}")

    @staticmethod
    def n_coef(xy_degree: int, depth_degree: int) -> int:
        return 3 * depth_degree * (xy_degree + 1) * (xy_degree + 2) // 2

    @staticmethod
    def features(e_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike, xy_degree: int = 3,
                 depth_degree: int = 2) -> NDArray[np.float64]:
        """The model's features (n, ``n_coef``) from the deflections e_mm (n, 3)."""
        # Scaled to about [-1, 1] over the workspace, so the powers stay well conditioned.
        u, v = np.asarray(x_mm, np.float64) / 50.0, np.asarray(y_mm, np.float64) / 50.0
        mons = [u**i * v**j for i in range(xy_degree + 1) for j in range(xy_degree + 1 - i)]
        cols = []
        for a in range(1, depth_degree + 1):
            for q in np.atleast_2d(np.asarray(e_mm, np.float64)).T:
                qa = q**a / 50.0 ** (a - 1)
                cols.extend(qa * m for m in mons)
        return np.stack(cols, axis=-1)

    def apply_one(self, e0: float, e1: float, e2: float, x_mm: float, y_mm: float) -> float:
        """``apply`` for one sample in Python floats: no arrays, for the per-frame path."""
        u, v = x_mm / 50.0, y_mm / 50.0
        c, k, acc = self.coef, 0, 0.0
        for a in range(1, self.depth_degree + 1):
            for e in (e0, e1, e2):
                ea = e**a / 50.0 ** (a - 1)
                for i in range(self.xy_degree + 1):
                    eu = ea * u**i
                    for j in range(self.xy_degree + 1 - i):
                        acc += c[k] * eu * v**j
                        k += 1
        return acc

    def apply(self, e_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike) -> NDArray[np.float64]:
        """The corrected depth from the deflections e_mm (n, 3) at centroids (x, y)."""
        return self.features(e_mm, x_mm, y_mm, self.xy_degree, self.depth_degree) \
            @ np.asarray(self.coef)

    @classmethod
    def identity(cls, xy_degree: int = 3, depth_degree: int = 2,
                 sensors_mm: Sequence[Sequence[float]] = PAPER_SENSORS_MM) -> SagCorrection:
        """depth = the plane: the barycentric weights of ``sensors_mm`` written as
        polynomials of (x, y) (none for ``xy_degree`` 0, which cannot hold them)."""
        coef = np.zeros(cls.n_coef(xy_degree, depth_degree))
        s = np.asarray(sensors_mm, np.float64)
        m_inv = np.linalg.inv(np.vstack([s[:, 0], s[:, 1], np.ones(3)]))
        # w_i = m_inv[i, 0] x + m_inv[i, 1] y + m_inv[i, 2], in u = x/50, v = y/50.
        mons = [(i, j) for i in range(xy_degree + 1) for j in range(xy_degree + 1 - i)]
        per = len(mons)
        if xy_degree >= 1:
            for k in range(3):
                coef[k * per + mons.index((0, 0))] = m_inv[k, 2]
                coef[k * per + mons.index((1, 0))] = m_inv[k, 0] * 50.0
                coef[k * per + mons.index((0, 1))] = m_inv[k, 1] * 50.0
        return cls(tuple(float(c) for c in coef), xy_degree, depth_degree)

    @staticmethod
    def penalty(xy_degree: int = 3, depth_degree: int = 2) -> NDArray[np.float64]:
        """Ridge weight per term: (order in x, y plus extra power of the input) squared,
        at least 1, so higher orders give way first when data are few."""
        return np.array([max(float(i + j + a - 1) ** 2, 1.0)
                         for a in range(1, depth_degree + 1)
                         for _ in range(3)
                         for i in range(xy_degree + 1)
                         for j in range(xy_degree + 1 - i)])

    @classmethod
    def _solve(cls, gram: NDArray[np.float64], rhs: NDArray[np.float64], mean_sq: float,
               xy_degree: int, depth_degree: int, ridge: float,
               sensors_mm: Sequence[Sequence[float]]) -> NDArray[np.float64]:
        """The ridge solution from the normal equations ``F'F``, ``F't`` (``fit``)."""
        prior = np.asarray(cls.identity(xy_degree, depth_degree, sensors_mm).coef)
        lam = ridge * mean_sq * np.diag(cls.penalty(xy_degree, depth_degree))
        return np.linalg.solve(gram + lam, rhs + lam @ prior)

    @classmethod
    def _design(cls, e_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike, truth_mm: ArrayLike,
                xy_degree: int, depth_degree: int
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """The features and truth of the usable samples, and which samples those are."""
        n = cls.n_coef(xy_degree, depth_degree)
        f = cls.features(e_mm, x_mm, y_mm, xy_degree, depth_degree)
        t = np.asarray(truth_mm, np.float64)
        ok = np.all(np.isfinite(f), axis=1) & np.isfinite(t)
        if int(ok.sum()) < 3 * n:
            raise ValueError(f"correction: need at least {3 * n} calibration samples with "
                             f"valid readings, got {int(ok.sum())}")
        return f[ok], t[ok], ok

    @classmethod
    def fit(
        cls, e_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike, truth_mm: ArrayLike,
        xy_degree: int = 3, depth_degree: int = 2, ridge: float = 1e-2,
        sensors_mm: Sequence[Sequence[float]] = PAPER_SENSORS_MM,
    ) -> SagCorrection:
        """Ridge least squares of the true depth on the features, the ridge (relative to
        the features' mean square) weighted by ``penalty`` and shrinking towards the
        plane of the nominal ``sensors_mm``, so sparse data (few press positions) cannot
        run away."""
        f, t, _ = cls._design(e_mm, x_mm, y_mm, truth_mm, xy_degree, depth_degree)
        coef = cls._solve(f.T @ f, f.T @ t, float(np.mean(np.sum(f * f, axis=1))),
                          xy_degree, depth_degree, ridge, sensors_mm)
        return cls(tuple(float(c) for c in coef), xy_degree, depth_degree)

    @classmethod
    def fit_cv(
        cls, e_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike, truth_mm: ArrayLike,
        groups: ArrayLike, xy_degree: int = 3, depth_degree: int = 2,
        ridges: Sequence[float] = (1e-4, 1e-3, 1e-2, 1e-1, 1.0),
        sensors_mm: Sequence[Sequence[float]] = PAPER_SENSORS_MM,
    ) -> tuple[SagCorrection, float, dict[float, float]]:
        """The ridge chosen by leave-one-group-out cross-validation over ``groups`` (press
        numbers: each press scored by the fit on all the others), then fitted on all
        data. Returns the correction, its held-out RMSE and the RMSE per ridge tried.

        One press out at a time asks what a user needs: the depth at a place and depth
        between the presses recorded. A split into two halves (even and odd presses)
        leaves out a whole column of a press grid, and so scores extrapolation instead.
        Each press's normal equations are summed once and subtracted from the total, so
        a fold costs one small solve."""
        f, t, ok = cls._design(e_mm, x_mm, y_mm, truth_mm, xy_degree, depth_degree)
        g = np.asarray(groups)[ok]
        labels, inv = np.unique(g, return_inverse=True)
        if labels.size < 2:
            raise ValueError("correction: cross-validation needs at least two presses")
        sq = np.sum(f * f, axis=1)
        parts = [(f[inv == k], t[inv == k], sq[inv == k]) for k in range(labels.size)]
        grams = [(fk.T @ fk, fk.T @ tk, float(sk.sum()), tk.size) for fk, tk, sk in parts]
        gram_all, rhs_all = f.T @ f, f.T @ t
        sq_all, n_all = float(sq.sum()), t.size
        scores: dict[float, float] = {}
        for ridge in ridges:
            err2 = 0.0
            for (fk, tk, _), (gk, bk, sk, nk) in zip(parts, grams, strict=True):
                coef = cls._solve(gram_all - gk, rhs_all - bk, (sq_all - sk) / (n_all - nk),
                                  xy_degree, depth_degree, ridge, sensors_mm)
                err2 += float(np.sum((fk @ coef - tk) ** 2))
            scores[ridge] = math.sqrt(err2 / n_all)
        best = min(scores, key=lambda r: scores[r])
        final = cls.fit(e_mm, x_mm, y_mm, truth_mm, xy_degree, depth_degree, best, sensors_mm)
        return final, scores[best], scores


def rmse(a: ArrayLike, b: ArrayLike) -> float:
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d * d))) if d.size else math.nan


# --------------------------------------------------------------------------- estimator


@dataclass
class IndentationResult:
    """Per sample: the indentation (mm, positive down; NaN when invalid), the plane's
    estimate -delta before correction, ``IRFlag`` bits and the sensors' deflections."""

    indentation_mm: NDArray[np.float64]
    plane_mm: NDArray[np.float64]
    flags: NDArray[np.int64]
    #: Each sensor's deflection from its rest distance, positive down, (n, 3).
    deflection_mm: NDArray[np.float64] | None = None

    @property
    def valid(self) -> NDArray[np.bool_]:
        return (self.flags & int(INVALID)) == 0


@dataclass(frozen=True)
class IndentationEstimator:
    """Sensor positions, eq. (1) per sensor, rest distances and an optional correction.

    ``baseline_mm`` None means "not known yet": ``with_baseline_from`` resolves it by the
    recording format's rule; until then ``base_to_fabric_mm`` is used for all three.
    """

    sensors_mm: tuple[tuple[float, float], ...] = PAPER_SENSORS_MM
    poly_cm: tuple[tuple[float, ...], ...] = (PAPER_POLY_CM,) * 3
    valid_range_v: tuple[tuple[float, float], ...] = (VALID_VOLTAGE_RANGE_V,) * 3
    base_to_fabric_mm: float = 100.0
    baseline_mm: tuple[float, float, float] | None = None
    correction: SagCorrection | None = None
    #: Each sensor's own measurement period, held in between (``resample_distances_mm``).
    sensor_period_s: tuple[float, float, float] = (SENSOR_PERIOD_S,) * 3

    def __post_init__(self) -> None:
        plane_weights(self.sensors_mm, 0.0, 0.0)  # collinear sensors: fail now, not later
        s = np.asarray(self.sensors_mm, np.float64)
        # Barycentric weights are inv(M) @ [x, y, 1]: invert once, not per sample.
        m_inv = np.linalg.inv(np.vstack([s[:, 0], s[:, 1], np.ones(3)]))
        object.__setattr__(self, "_m_inv", m_inv)
        # The same in Python floats for ``depth_at``, with the rest distances.
        object.__setattr__(self, "_w_rows", tuple(tuple(float(c) for c in row) for row in m_inv))
        object.__setattr__(self, "_rest", tuple(float(r) for r in self.rest_mm()))

    @classmethod
    def from_config(
        cls, config: IRConfig, sensors_mm: Sequence[Sequence[float]] | None = None,
        baseline_mm: Sequence[float] | None = None, base_to_fabric_mm: float | None = None,
    ) -> IndentationEstimator:
        """From the device configuration; a recording's ``meta.json`` ``ir`` values, when
        given, take precedence (they describe the device that made the recording)."""
        sensors = sensors_mm if sensors_mm is not None else config.sensors_mm
        base = baseline_mm if baseline_mm is not None else config.baseline_mm
        return cls(
            sensors_mm=tuple((float(x), float(y)) for x, y in sensors),
            poly_cm=tuple(tuple(p) for p in config.poly_cm),
            valid_range_v=tuple(tuple(r) for r in config.valid_range_v),  # type: ignore[misc]
            base_to_fabric_mm=float(base_to_fabric_mm if base_to_fabric_mm is not None
                                    else config.base_to_fabric_mm),
            baseline_mm=None if base is None else tuple(float(b) for b in base),  # type: ignore[arg-type]
            correction=SagCorrection(tuple(config.correction_coef), config.correction_xy_degree,
                                     config.correction_depth_degree)
            if config.correction_coef else None,
            sensor_period_s=tuple(float(t) for t in config.sensor_period_s),  # type: ignore[arg-type]
        )

    def distances_mm(self, volts: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Eq. (1) per sensor with this device's polynomials; see ``sensor_distances_mm``."""
        return sensor_distances_mm(volts, self.poly_cm, self.valid_range_v)

    def rest_mm(self) -> NDArray[np.float64]:
        if self.baseline_mm is not None:
            return np.asarray(self.baseline_mm, np.float64)
        return np.full(3, self.base_to_fabric_mm)

    def with_baseline_from(
        self, volts: ArrayLike, no_contact: ArrayLike, min_samples: int = 5,
    ) -> IndentationEstimator:
        """The estimator with its rest distances resolved: kept if given, else the
        interquartile mean of the samples marked ``no_contact``
        (``estimate_baseline_mm``), else ``base_to_fabric_mm``."""
        if self.baseline_mm is not None:
            return self
        d, _ = self.distances_mm(volts)
        est = estimate_baseline_mm(d, no_contact, min_samples)
        base = resolve_baseline_mm(None, est, self.base_to_fabric_mm)
        return replace(self, baseline_mm=tuple(float(b) for b in base))

    def estimate_from_distances(
        self, distances_mm: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike,
        contact: ArrayLike | None = None, flags: ArrayLike | None = None,
    ) -> IndentationResult:
        """Indentation from distances[n, 3] (NaN = invalid) at centroids (x, y)."""
        d = np.atleast_2d(np.asarray(distances_mm, np.float64))
        n = d.shape[0]
        x = np.broadcast_to(np.asarray(x_mm, np.float64), (n,))
        y = np.broadcast_to(np.asarray(y_mm, np.float64), (n,))
        fl = np.zeros(n, np.int64) if flags is None else np.array(flags, np.int64).reshape(n)
        for i in range(3):
            fl |= np.where(np.isfinite(d[:, i]), 0, int(_SENSOR_INVALID[i]))
        touching = np.ones(n, bool) if contact is None else \
            np.broadcast_to(np.asarray(contact, bool), (n,))
        has_xy = np.isfinite(x) & np.isfinite(y)
        fl |= np.where(touching & ~has_xy, int(IRFlag.NO_CENTROID), 0)
        fl |= np.where(touching, 0, int(IRFlag.NO_CONTACT))
        # Evaluate at (0, 0) where there is no centroid; those samples are masked below.
        xs, ys = np.where(has_xy, x, 0.0), np.where(has_xy, y, 0.0)
        w = (self._m_inv @ np.vstack([xs, ys, np.ones(n)])).T  # type: ignore[attr-defined]
        fl |= np.where(has_xy & np.any(w < -1e-9, axis=1), int(IRFlag.EXTRAPOLATED), 0)
        e = d - self.rest_mm()  # negative when the finger presses the fabric down
        plane = -np.sum(w * e, axis=1)  # indentation = -delta
        depth = plane if self.correction is None else self.correction.apply(-e, xs, ys)
        bad = (fl & int(INVALID)) != 0
        plane = np.where(bad, np.nan, plane)
        depth = np.where(bad, np.nan, depth)
        # Without contact the format says 0, whatever the sensors read (noise, drift).
        depth = np.where(touching, depth, 0.0)
        plane = np.where(touching, plane, 0.0)
        return IndentationResult(depth, plane, fl, -e)

    def estimate(
        self, volts: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike,
        contact: ArrayLike | None = None,
    ) -> IndentationResult:
        """Vectorised: volts[n, 3] and centroids (x, y)[n] -> indentation per sample."""
        d, flags = self.distances_mm(volts)
        return self.estimate_from_distances(d, x_mm, y_mm, contact, flags)

    def depth_at(self, d0_mm: float, d1_mm: float, d2_mm: float, x_mm: float,
                 y_mm: float) -> float:
        """One contact sample's indentation from its distances, in Python floats (no
        arrays: the per-frame path); the arithmetic of ``estimate_from_distances``, NaN
        where a distance or the centroid is NaN. Flags are the caller's."""
        (a0, b0, c0), (a1, b1, c1), (a2, b2, c2) = self._w_rows  # type: ignore[attr-defined]
        r0, r1, r2 = self._rest  # type: ignore[attr-defined]
        e0, e1, e2 = r0 - d0_mm, r1 - d1_mm, r2 - d2_mm  # positive down
        if self.correction is not None:
            return self.correction.apply_one(e0, e1, e2, x_mm, y_mm)
        return ((a0 * x_mm + b0 * y_mm + c0) * e0 + (a1 * x_mm + b1 * y_mm + c1) * e1
                + (a2 * x_mm + b2 * y_mm + c2) * e2)

    def estimate_one(
        self, volts: Sequence[float], x_mm: float, y_mm: float, contact: bool = True,
    ) -> tuple[float, IRFlag]:
        """Per-sample path for a live loop; the same arithmetic as ``estimate``."""
        r = self.estimate(np.asarray(volts, np.float64).reshape(1, 3), [x_mm], [y_mm],
                          [contact])
        return float(r.indentation_mm[0]), IRFlag(int(r.flags[0]))


# --------------------------------------------------------------------------- recordings


def measurement_time_s(t_s: float, prev_board_t_s: float, sensor_period_s: float) -> float:
    """When a new reading first seen in the board sample at ``t_s`` was measured.

    A sensor holding its output for ``sensor_period_s`` changes it at a moment the board
    does not see: a value first read at ``t_s`` was measured after the previous board
    sample (``prev_board_t_s``) and, for a sensor faster than the board, within its own
    period; taken in the middle, ``t_s - min(t_s - prev, T) / 2``. ``T = 0`` (or no
    previous sample and ``T = 0``): the sample is the measurement, at ``t_s``."""
    return t_s - min(t_s - prev_board_t_s, sensor_period_s) / 2


def is_held(z: float, held_z: float, t_s: float, new_t_s: float,
            sensor_period_s: float) -> bool:
    """A board sample repeats the sensor's held output (not a new measurement): the same
    reading as the last sample, less than one sensor period after the last new one (a
    sensor that read the same value again later has measured again)."""
    return z == held_z and t_s - new_t_s < sensor_period_s


def resample_distances_mm(
    t_ir_s: ArrayLike, distances_mm: ArrayLike, flags: ArrayLike, t_query_s: ArrayLike,
    max_gap_s: float = 0.1, sensor_period_s: Sequence[float] = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """IR distances at other times (video frames) by linear interpolation between the two
    neighbouring measurements. An invalid neighbour makes the result NaN (never bridged); a
    query with no board sample within ``max_gap_s`` on either side is flagged ``NO_IR``.

    With each sensor's own ``sensor_period_s`` (``SENSOR_PERIOD_S`` for the Sharp sensor),
    the board samples that repeat a held output are dropped and each new reading is placed
    at its measurement time (``is_held``, ``measurement_time_s``): the held output lags
    the fabric by up to one period, 8 ms on average (1.3 mm on an 80 mm/s tap) when taken
    at the board's times. 0: every board sample is a measurement at its own time."""
    t = np.asarray(t_ir_s, np.float64)
    d = np.atleast_2d(np.asarray(distances_mm, np.float64))
    fl = np.asarray(flags, np.int64)
    q = np.asarray(t_query_s, np.float64)
    out_fl = np.zeros(q.size, np.int64)
    if t.size == 0:
        return np.full((q.size, 3), np.nan), out_fl | int(IRFlag.NO_IR)
    hi = np.clip(np.searchsorted(t, q, side="left"), 0, t.size - 1)
    lo = np.clip(hi - 1, 0, t.size - 1)
    near = (np.abs(q - t[lo]) <= max_gap_s) & (np.abs(t[hi] - q) <= max_gap_s)
    out_fl |= np.where(near, fl[lo] | fl[hi], int(IRFlag.NO_IR))
    out = np.empty((q.size, 3))
    for i in range(3):
        keep = np.ones(t.size, bool)
        t_meas = t.copy()
        if sensor_period_s[i] > 0:
            held_z, new_t, prev_t = math.nan, -math.inf, -math.inf
            for k, (tk, z) in enumerate(zip(t.tolist(), d[:, i].tolist(), strict=True)):
                if is_held(z, held_z, tk, new_t, sensor_period_s[i]):
                    keep[k] = False
                else:
                    new_t = tk
                    t_meas[k] = measurement_time_s(tk, prev_t, sensor_period_s[i])
                held_z, prev_t = z, tk
        out[:, i] = _interp_never_bridging(t_meas[keep], d[keep, i], q)
    out[~near] = np.nan
    return out, out_fl


def _interp_never_bridging(t: NDArray[np.float64], z: NDArray[np.float64],
                           q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Linear interpolation of z(t) at q, held flat beyond the ends; NaN in either
    neighbour stays NaN."""
    hi = np.clip(np.searchsorted(t, q, side="left"), 0, t.size - 1)
    lo = np.clip(hi - 1, 0, t.size - 1)
    lo = np.where(t[hi] == q, hi, lo)
    span = t[hi] - t[lo]
    frac = np.where(span > 0, (q - t[lo]) / np.where(span > 0, span, 1.0), 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    return z[lo] * (1 - frac) + z[hi] * frac


#: Causal distance filter (``filter_distances_mm``): white-acceleration PSD of the fabric
#: above each sensor, mm^2/s^3, and the sensor's noise per measurement, mm (6 mV on
#: ~80 mm/V at rest: 0.45-0.55 mm, docs/teleop.md).
DISTANCE_ACCEL_PSD_MM2_S3 = 1.0e4
DISTANCE_NOISE_MM = 0.5


@dataclass(slots=True)
class DistanceFilterState:
    """Per sensor: [distance mm, velocity mm/s], its covariance and the time of the last
    measurement used (NaN: none yet); the last board sample's reading and the board time
    of the last new reading (to tell a held output from a new measurement); the time and
    flags of the last board sample; ``out``, the buffer the distances are returned in.
    Updated in place: no allocation per frame."""

    x: NDArray[np.float64]  # (3, 2)
    p: NDArray[np.float64]  # (3, 2, 2)
    t_s: NDArray[np.float64]  # (3,)
    held_mm: NDArray[np.float64]  # (3,)
    new_t_s: NDArray[np.float64]  # (3,)
    last_t_s: float
    last_flags: int
    out: NDArray[np.float64]  # (3,)

    @classmethod
    def initial(cls) -> DistanceFilterState:
        return cls(np.zeros((3, 2)), np.zeros((3, 2, 2)), np.full(3, np.nan),
                   np.full(3, np.nan), np.full(3, -np.inf), -math.inf, 0, np.empty(3))


def filter_distances_mm(
    state: DistanceFilterState, t_ir_s: ArrayLike, distances_mm: ArrayLike,
    flags: ArrayLike, t_query_s: float, max_gap_s: float = 0.1,
    accel_psd: float = DISTANCE_ACCEL_PSD_MM2_S3, noise_mm: float = DISTANCE_NOISE_MM,
    sensor_period_s: Sequence[float] = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], int, DistanceFilterState]:
    """The IR distances at ``t_query_s`` from the samples up to it, causally: a
    constant-velocity Kalman filter per sensor (white acceleration, Bar-Shalom ch. 6)
    updated with each new measurement, then predicted to the query time.

    ``t_ir_s``, ``distances_mm`` [n, 3], ``flags`` are the board samples not yet given
    (all at or before ``t_query_s``); returns (distances [3], flags, state), the state
    updated in place and the distances in its ``out`` buffer (copy them to keep them).
    Interpolating between the samples either side of a frame needs one taken after it
    (up to a board period ahead); the filter also averages the sensor's noise. With the
    sensors' ``sensor_period_s`` a board sample repeating a held output is not a
    measurement, and a new reading is placed at its measurement time (``is_held``,
    ``measurement_time_s``, as ``resample_distances_mm``). An invalid sample (NaN) is
    not used, and while a sensor's latest sample is invalid its distance is NaN (never
    bridged); no sample within ``max_gap_s`` gives ``NO_IR``.
    """
    x, p, ts, held, new_t = state.x, state.p, state.t_s, state.held_mm, state.new_t_s
    r = noise_mm**2
    q = accel_psd
    t = np.asarray(t_ir_s, np.float64).reshape(-1)
    d = np.asarray(distances_mm, np.float64).reshape(-1, 3)
    fl = np.asarray(flags, np.int64).reshape(-1)
    n = t.size
    # Per sensor in Python floats: a 2-state filter in 2x2 NumPy arrays spends its time in
    # NumPy's call overhead (about 40 us per sample and sensor against 2 us).
    for i in range(3):
        period = float(sensor_period_s[i])
        x0, x1 = float(x[i, 0]), float(x[i, 1])
        p00, p01, p10, p11 = float(p[i, 0, 0]), float(p[i, 0, 1]), float(p[i, 1, 0]), \
            float(p[i, 1, 1])
        ti, held_z, new_ti = float(ts[i]), float(held[i]), float(new_t[i])
        prev_t = state.last_t_s
        for k in range(n):
            tk, z = float(t[k]), float(d[k, i])
            board_prev, prev_t = prev_t, tk
            if not math.isfinite(z):  # an invalid sample is not used
                held_z = math.nan
                continue
            if is_held(z, held_z, tk, new_ti, period):
                continue
            held_z, new_ti = z, tk
            tm = measurement_time_s(tk, board_prev, period)
            if not math.isfinite(ti):  # first measurement: at rest, velocity unknown
                x0, x1 = z, 0.0
                p00, p01, p10, p11 = r, 0.0, 0.0, 100.0**2
                ti = tm
                continue
            # Predict, x = F x, P = F P F' + Q (F = [[1, dt], [0, 1]], Q of white
            # acceleration: q [[dt^3/3, dt^2/2], [dt^2/2, dt]]) ...
            dt = max(tm - ti, 0.0)
            x0 = x0 + dt * x1
            a00 = p00 + dt * p10
            a01 = p01 + dt * p11
            p00 = a00 + a01 * dt + q * dt**3 / 3
            p01 = a01 + q * dt**2 / 2
            p10 = p10 + dt * p11 + q * dt**2 / 2
            p11 = p11 + q * dt
            # ... then update with z: K = P[:, 0] / (P00 + r), x += K (z - x0), P -= K P[0, :].
            sk = p00 + r
            g0, g1 = p00 / sk, p10 / sk
            innov = z - x0
            x0, x1 = x0 + g0 * innov, x1 + g1 * innov
            p00, p01, p10, p11 = p00 - g0 * p00, p01 - g0 * p01, p10 - g1 * p00, p11 - g1 * p01
            ti = tm
        x[i, 0], x[i, 1] = x0, x1
        p[i, 0, 0], p[i, 0, 1], p[i, 1, 0], p[i, 1, 1] = p00, p01, p10, p11
        ts[i], held[i], new_t[i] = ti, held_z, new_ti
    if n:
        state.last_t_s, state.last_flags = float(t[-1]), int(fl[-1])
    out = state.out
    no_ir = t_query_s - state.last_t_s > max_gap_s
    for i in range(3):
        # NaN for a sensor never seen; never bridged across an invalid latest sample.
        invalid = no_ir or bool(state.last_flags & int(_SENSOR_INVALID[i]))
        out[i] = math.nan if invalid else float(x[i, 0] + (t_query_s - ts[i]) * x[i, 1])
    return out, int(IRFlag.NO_IR) if no_ir else state.last_flags, state


#: IR samples within this time of the first contact frame are not used for the rest
#: distances (a finger landing is already pushing the fabric).
BASELINE_MARGIN_S = 0.1


def before_first_contact_mask(
    t_ir_s: ArrayLike, t_frames_s: ArrayLike, contact: ArrayLike,
    margin_s: float = BASELINE_MARGIN_S,
) -> NDArray[np.bool_]:
    """The IR samples the rest distances come from: those taken more than ``margin_s``
    before the first contact frame (all of them in a recording without contact). The
    same rule as the live station's (``vision.stream.LiveIndentation``), which knows
    nothing later when the finger first lands, so a calibration and ``fydpad track``
    read a recording with the same rest distances."""
    t = np.asarray(t_ir_s, np.float64)
    tf = np.asarray(t_frames_s, np.float64)
    c = np.asarray(contact, bool)
    if not c.any():
        return np.ones(t.size, bool)
    return t < float(tf[c].min()) - margin_s


def indentation_at_frames(
    estimator: IndentationEstimator,
    t_ir_s: ArrayLike, volts: ArrayLike,
    t_frames_s: ArrayLike, contact: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike,
    max_gap_s: float = 0.1,
) -> tuple[IndentationResult, IndentationEstimator]:
    """What ``fydpad track`` needs: the indentation at each video frame of a recording
    from its ``ir.csv`` samples and the tracked centroids.

    Rest distances are resolved first (given, else from the IR samples before the first
    contact, ``before_first_contact_mask``, else ``base_to_fabric_mm``); returns the
    result and the estimator actually used (with its baseline), so the caller can report
    it.
    """
    est = estimator.with_baseline_from(volts,
                                      before_first_contact_mask(t_ir_s, t_frames_s, contact))
    d, flags = est.distances_mm(volts)
    d_f, fl_f = filter_distances_at_frames(t_ir_s, d, flags, t_frames_s, max_gap_s,
                                           est.sensor_period_s)
    return est.estimate_from_distances(d_f, x_mm, y_mm, contact, fl_f), est


def filter_distances_at_frames(
    t_ir_s: ArrayLike, distances_mm: ArrayLike, flags: ArrayLike, t_frames_s: ArrayLike,
    max_gap_s: float = 0.1, sensor_period_s: Sequence[float] = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The causal filter's distances and flags at each frame, as the product computes
    them (``vision.stream.LiveIndentation``): at each frame, the board samples up to it
    not yet given go to ``filter_distances_mm``, predicted to the frame's time (never
    before the newest sample). A correction fitted on these is fitted on the readings
    it is applied to."""
    t = np.asarray(t_ir_s, np.float64).reshape(-1)
    d = np.asarray(distances_mm, np.float64).reshape(-1, 3)
    fl = np.asarray(flags, np.int64).reshape(-1)
    tf = np.asarray(t_frames_s, np.float64).reshape(-1)
    out = np.empty((tf.size, 3))
    out_fl = np.zeros(tf.size, np.int64)
    state = DistanceFilterState.initial()
    start = 0
    for j, t_s in enumerate(tf.tolist()):
        end = max(int(np.searchsorted(t, t_s, side="right")), start)
        t_q = max(t_s, float(t[end - 1])) if end > start else t_s
        dist, out_fl[j], state = filter_distances_mm(
            state, t[start:end], d[start:end], fl[start:end], t_q, max_gap_s,
            sensor_period_s=sensor_period_s)
        out[j] = dist
        start = end
    return out, out_fl


# --------------------------------------------------------------------------- eq. (1) refit


class IRCalibrationError(UserError, ValueError):
    """(distance, voltage) pairs too few or degenerate for a fit; the message says why."""


@dataclass
class IRFit:
    """One sensor's refitted eq. (1): polynomial in cm (highest power first), its R^2 on
    distance, the RMS residual in mm and the voltage range it was fitted over (its
    valid range: a fit is not trusted beyond its data)."""

    poly_cm: tuple[float, ...]
    r2: float
    rms_mm: float
    valid_range_v: tuple[float, float]
    n_points: int
    monotonic: bool


def fit_ir_polynomial(
    distance_mm: ArrayLike, voltage_v: ArrayLike, degree: int = 5,
) -> IRFit:
    """Least-squares fit of distance (cm, as eq. (1)) on voltage, 5th order by default.

    Needs at least ``degree + 3`` points over ``degree + 1`` distinct voltages spanning
    at least 0.2 V, and distance falling as voltage rises (the Sharp sensor's curve).
    ``monotonic`` says whether the fit falls over its whole range; where it does not,
    two distances read alike and the calibration should be redone with more points.
    """
    d = np.asarray(distance_mm, np.float64)
    v = np.asarray(voltage_v, np.float64)
    ok = np.isfinite(d) & np.isfinite(v)
    d, v = d[ok], v[ok]
    if d.size < degree + 3:
        raise IRCalibrationError(f"{d.size} points, need at least {degree + 3} for a "
                                 f"degree-{degree} fit")
    if np.any(d <= 0):
        raise IRCalibrationError("distances must be positive (mm)")
    if np.ptp(v) < 0.2 or np.unique(v).size < degree + 1:
        raise IRCalibrationError(
            f"voltage nearly constant ({v.min():.3f}-{v.max():.3f} V over {np.unique(v).size} "
            f"distinct values): sensor disconnected or the target did not move?")
    if np.corrcoef(v, d)[0, 1] >= 0:
        raise IRCalibrationError("voltage rises with distance: a Sharp sensor's falls "
                                 "(columns swapped?)")
    poly = np.polyfit(v, d / 10.0, degree)
    resid_mm = d - np.polyval(poly, v) * 10.0
    ss_tot = float(np.sum((d - d.mean()) ** 2))
    r2 = 1.0 - float(np.sum(resid_mm**2)) / ss_tot
    grid = np.linspace(v.min(), v.max(), 512)
    monotonic = bool(np.all(np.polyval(np.polyder(poly), grid) <= 0))
    return IRFit(
        poly_cm=tuple(float(c) for c in poly), r2=r2,
        rms_mm=float(np.sqrt(np.mean(resid_mm**2))),
        valid_range_v=(float(v.min()), float(v.max())), n_points=int(d.size),
        monotonic=monotonic,
    )
