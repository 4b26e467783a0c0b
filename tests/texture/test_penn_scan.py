"""Strokes rendered from a HaTT model (texture_scans.penn_scan): a surface at one speed is
the same whatever else the stroke visits."""

from __future__ import annotations

import numpy as np

from fydpad.synth.texture_scans import hand_speed, penn_scan, plateau_speed
from fydpad.texture.families.penn.toolkit import PennModelSet
from fydpad.texture.lpc.dft321 import preprocess
from tests.texture.lpc_polys import poly_to_lsf, reflection_to_poly

FS = 1000.0


def _quiet_when_slow() -> PennModelSet:
    """An AR(4) surface silent up to 15 mm/s (var 0, as the toolkit's rest vertices) and
    loud at 60 mm/s: a slow stroke holds little but the sensor noise and the impacts."""
    lsf = poly_to_lsf(reflection_to_poly([0.6, -0.4, 0.3, 0.1]))
    speeds = np.array([0.0, 15.0, 60.0, 0.0, 15.0, 60.0])
    forces = np.array([0.0, 0.0, 0.0, 3.0, 3.0, 3.0])
    tri = np.array([[0, 1, 3], [1, 4, 3], [1, 2, 4], [2, 5, 4]])
    return PennModelSet("quiet", FS, speeds, forces, tri, np.tile(lsf, (6, 1)),
                        np.zeros((6, 0)), np.array([0.0, 0.0, 0.5, 0.0, 0.0, 0.5]),
                        np.ones(6), 60.0, 3.0)


def test_slow_part_of_a_fast_stroke_is_a_slow_stroke():
    """Impacts are sized by the texture where they happen: the 10 mm/s plateau of a
    10-40 mm/s stroke has the level of a 10 mm/s stroke (sized by the whole stroke's
    RMS, the plateau was 20 dB louder here)."""
    ms = _quiet_when_slow()
    rng = np.random.default_rng(5)
    mixed = penn_scan(ms, plateau_speed((10.0, 40.0), 20.0, FS, rng), seed=1)
    slow = penn_scan(ms, hand_speed(10.0, 10.0, FS, rng, 0.3), seed=2)

    def rms_db(scan, t0_s: float, t1_s: float) -> float:
        x = preprocess(scan.acc, FS, 10.0)[round(t0_s * FS):round(t1_s * FS)]
        return 10 * np.log10(np.mean(x * x))

    plateau, alone = rms_db(mixed, 1.0, 8.5), rms_db(slow, 1.0, 9.0)
    loud = rms_db(mixed, 11.5, 19.0)
    assert loud - alone > 20.0  # the fast part is loud: the check below can fail
    assert abs(plateau - alone) < 1.5
