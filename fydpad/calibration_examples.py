"""Sample inputs for the calibration commands (``--example DIR``): what a lab measures,
made from a known device so a fit can be checked against it.

- IR pairs: three sensors whose curves are the paper's eq. (1) (Bianchi et al. 2015)
  stretched by 0.96, 1.00 and 1.05 in distance (parts differ), read at 40-300 mm every
  10 mm with 5 mV of noise;
- load cell: offset 12 000 counts, gain 1.05 x the CZL616C's nominal, three readings
  each under 0, 50, 100, 200, 500 and 700 g with 30 counts of noise.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vision.config import G_M_S2, NOMINAL_FORCE_GAIN_N_PER_COUNT
from vision.ir import distance_to_voltage_v

#: Each example sensor's distance stretch against eq. (1).
IR_STRETCH = (0.96, 1.00, 1.05)
IR_DISTANCES_MM = np.arange(40.0, 301.0, 10.0)
IR_NOISE_V = 0.005
FORCE_OFFSET_COUNTS = 12000.0
FORCE_GAIN_N_PER_COUNT = 1.05 * NOMINAL_FORCE_GAIN_N_PER_COUNT
FORCE_MASSES_G = (0.0, 50.0, 100.0, 200.0, 500.0, 700.0)
FORCE_NOISE_COUNTS = 30.0


def example_ir_volts(distance_mm: np.ndarray, sensor: int) -> np.ndarray:
    """The example sensor's noise-free voltage at ``distance_mm`` (the truth)."""
    return distance_to_voltage_v(np.asarray(distance_mm, float) / IR_STRETCH[sensor])


def write_ir_example(out_dir: Path, seed: int = 0) -> Path:
    """``ir_pairs.csv`` (distance_mm,v0,v1,v2) in ``out_dir``."""
    rng = np.random.default_rng(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    d = IR_DISTANCES_MM
    volts = [example_ir_volts(d, i) + rng.normal(0, IR_NOISE_V, d.size) for i in range(3)]
    path = out_dir / "ir_pairs.csv"
    rows = ["distance_mm,v0,v1,v2"] + [
        f"{d[k]:.1f},{volts[0][k]:.4f},{volts[1][k]:.4f},{volts[2][k]:.4f}"
        for k in range(d.size)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def write_force_example(out_dir: Path, seed: int = 0) -> Path:
    """``force_weights.csv`` (mass_g,raw) in ``out_dir``."""
    rng = np.random.default_rng(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = ["mass_g,raw"]
    for mass_g in FORCE_MASSES_G:
        for _ in range(3):
            raw = (FORCE_OFFSET_COUNTS + mass_g * 1e-3 * G_M_S2 / FORCE_GAIN_N_PER_COUNT
                   + rng.normal(0, FORCE_NOISE_COUNTS))
            rows.append(f"{mass_g:g},{round(raw)}")
    path = out_dir / "force_weights.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path
