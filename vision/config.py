"""Configuration dataclasses of the sensing package, with the paper's values as defaults.

Plain dataclasses of floats, ints, strings and tuples only, so that ``fydpad.config``
can read and write them as TOML sections. Validation that needs no I/O happens in
``__post_init__`` and raises ``ValueError`` naming the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from vision.ir import PAPER_POLY_CM, SENSOR_PERIOD_S, VALID_VOLTAGE_RANGE_V

#: Standard gravity, for masses in grams to forces in newtons.
G_M_S2 = 9.80665

#: The paper's sensor positions (x, y) in mm in the workspace frame, implied by eq. (2).
PAPER_SENSORS_MM: tuple[tuple[float, float], ...] = ((-22.0, -3.0), (0.0, 27.0), (22.0, -3.0))

#: Nominal load-cell gain for a CZL616C (1.0 mV/V) on a 24-bit bridge ADC (HX711, gain
#: 128, 5 V excitation): 7.65 N gives 5 mV of a +-19.5 mV input span over +-2^23 counts,
#: about 2.15e6 counts. Replace by ``fydpad calibrate force``.
NOMINAL_FORCE_GAIN_N_PER_COUNT = 780e-3 * G_M_S2 / (5.0 / (0.5 * 5000.0 / 128.0) * 2**23)


@dataclass
class IRConfig:
    """The three Sharp GP2Y0A41SK0F sensors on the base (paper II-A, II-C).

    ``poly_cm`` holds one eq. (1) polynomial per sensor (highest power first, result
    in cm); ``valid_range_v`` one (low, high) voltage range per sensor, outside which a
    reading is invalid. ``baseline_mm`` are the rest distances (no finger); None means
    "estimate from samples without contact, else ``base_to_fabric_mm``".
    """

    sensors_mm: tuple[tuple[float, float], ...] = PAPER_SENSORS_MM
    poly_cm: tuple[tuple[float, ...], ...] = (PAPER_POLY_CM, PAPER_POLY_CM, PAPER_POLY_CM)
    valid_range_v: tuple[tuple[float, float], ...] = (
        VALID_VOLTAGE_RANGE_V, VALID_VOLTAGE_RANGE_V, VALID_VOLTAGE_RANGE_V,
    )
    base_to_fabric_mm: float = 100.0
    baseline_mm: tuple[float, float, float] | None = None
    #: Correction beyond the plane (``vision.indentation.SagCorrection``: each sensor's
    #: deflection weighted by a polynomial of the centroid): its coefficients, empty for
    #: none; fitted by ``fydpad calibrate indentation``.
    correction_coef: tuple[float, ...] = ()
    correction_xy_degree: int = 3
    correction_depth_degree: int = 2
    #: Written by ``fydpad calibrate indentation``; only true is read (the correction on
    #: the plane estimate alone, false, is refused: refit the device).
    correction_per_sensor: bool = True
    #: Sensor board ADC: bits and reference voltage (the board's hello line overrides).
    adc_bits: int = 10
    adc_vref_v: float = 5.0
    #: Sample rate the board is asked for, in Hz.
    rate_hz: float = 100.0
    #: Each sensor's own measurement period, in s: it measures that often and holds its
    #: output in between, so the board reads repeats and readings up to a period old.
    sensor_period_s: tuple[float, float, float] = (SENSOR_PERIOD_S,) * 3
    #: Serial port of the sensor board ("" when there is none) and its speed.
    serial_port: str = ""
    serial_baud: int = 115200
    #: Seconds without a valid line before the board is reported silent.
    serial_timeout_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("sensors_mm", "poly_cm", "valid_range_v"):
            if len(getattr(self, name)) != 3:
                raise ValueError(f"{name}: expected one entry per sensor (3)")
        for i, p in enumerate(self.sensors_mm):
            if len(p) != 2:
                raise ValueError(f"sensors_mm[{i}]: expected [x, y] in mm")
        (x0, y0), (x1, y1), (x2, y2) = self.sensors_mm
        area2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        span = max(abs(x1 - x0), abs(x2 - x0), abs(y1 - y0), abs(y2 - y0), 1e-12)
        if abs(area2) < 1e-6 * span**2:
            raise ValueError(f"sensors_mm: {list(self.sensors_mm)} are collinear; eq. (2)'s "
                             "plane needs three non-collinear sensors")
        for i, poly in enumerate(self.poly_cm):
            if len(poly) < 2:
                raise ValueError(f"poly_cm[{i}]: expected at least two coefficients")
        for i, (lo, hi) in enumerate(self.valid_range_v):
            if not lo < hi:
                raise ValueError(f"valid_range_v[{i}]: low {lo} must be below high {hi}")
        if not self.base_to_fabric_mm > 0:
            raise ValueError("base_to_fabric_mm: must be positive")
        if self.baseline_mm is not None and (
            len(self.baseline_mm) != 3 or not all(math.isfinite(b) and b > 0
                                                  for b in self.baseline_mm)
        ):
            raise ValueError("baseline_mm: expected three positive distances in mm")
        if self.correction_coef and not self.correction_per_sensor:
            raise ValueError("correction_per_sensor: false is a correction on the plane "
                             "estimate alone, which is no longer read; refit the device with "
                             "`fydpad calibrate indentation` (docs/calibration_files.md)")
        if self.correction_coef:
            n = (3 * self.correction_depth_degree
                 * (self.correction_xy_degree + 1) * (self.correction_xy_degree + 2) // 2)
            if len(self.correction_coef) != n:
                raise ValueError(
                    f"correction_coef: expected {n} coefficients (three sensors) for "
                    f"correction_xy_degree {self.correction_xy_degree} and "
                    f"correction_depth_degree {self.correction_depth_degree}, "
                    f"got {len(self.correction_coef)}")
        if len(self.sensor_period_s) != 3 or not all(
                math.isfinite(t) and 0 <= t <= 1 for t in self.sensor_period_s):
            raise ValueError("sensor_period_s: expected three periods in s, 0-1 (0: the "
                             "board's samples are the measurements)")
        if not 1 <= self.adc_bits <= 24:
            raise ValueError("adc_bits: expected 1-24")
        if not self.adc_vref_v > 0 or not self.rate_hz > 0 or not self.serial_timeout_s > 0:
            raise ValueError("adc_vref_v, rate_hz and serial_timeout_s must be positive")


@dataclass
class ForceConfig:
    """The Phidgets CZL616C load cell (0-780 g, paper II-A): force_n = gain * (raw - offset)."""

    offset_counts: float = 0.0
    gain_n_per_count: float = NOMINAL_FORCE_GAIN_N_PER_COUNT
    full_scale_g: float = 780.0
    #: Raw counts at the ADC's rails (a signed 24-bit bridge ADC), also saturated.
    raw_min: int = -(2**23)
    raw_max: int = 2**23 - 1

    def __post_init__(self) -> None:
        if self.gain_n_per_count == 0 or not math.isfinite(self.gain_n_per_count):
            raise ValueError("gain_n_per_count: must be finite and non-zero")
        if not self.full_scale_g > 0:
            raise ValueError("full_scale_g: must be positive")
        if not self.raw_min < self.raw_max:
            raise ValueError("raw_min must be below raw_max")

    @property
    def full_scale_n(self) -> float:
        return self.full_scale_g * 1e-3 * G_M_S2
