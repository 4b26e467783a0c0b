"""HaTT test data: the toolkit's own synthesis at the model rate (``LPCvibration``,
Culbertson 2014), which renders the HaTT corpus's scans (:func:`texture_scans.penn_scan`),
and a writer of model sets in the toolkit's XML schema (synthetic model files).

The family that renders HaTT models at the station's rate is
:mod:`fydpad.texture.families.penn.render`.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.texture.families.penn.toolkit import PennModelSet, barycentric_weights
from fydpad.texture.lpc.lsf import lsf_to_poly

Array = NDArray[np.float64]


def interpolate(ms: PennModelSet, speed_mm_s: float, force_n: float
                ) -> tuple[Array, Array, float, float]:
    """(A, B, var, gain) at (speed, force): LSFs, var and gain weighted barycentrically."""
    w = barycentric_weights(ms, speed_mm_s, force_n)[0]
    idx = np.flatnonzero(w > 0)
    w = w[idx]
    a = lsf_to_poly(w @ ms.ar_lsf[idx])
    b = lsf_to_poly(w @ ms.ma_lsf[idx]) if ms.ma_lsf.shape[1] else np.array([1.0])
    return a, b, float(w @ ms.var[idx]), float(w @ ms.gain[idx])


class PennRenderer:
    """The ARMA synthesis at the model rate, state carried across blocks and models."""

    def __init__(self, ms: PennModelSet, seed: int | None = None):
        self.ms, self.rng = ms, np.random.default_rng(seed)
        self.p, self.q = ms.ar_lsf.shape[1], ms.ma_lsf.shape[1]
        self.y_hist, self.e_hist = np.zeros(self.p), np.zeros(self.q)  # newest first

    def block(self, speed_mm_s: float, force_n: float, n: int) -> Array:
        """``n`` samples at the model rate for one (speed, force)."""
        a, b, var, gain = interpolate(self.ms, speed_mm_s, force_n)
        e = self.rng.normal(0.0, np.sqrt(var), n)
        bb = gain * b
        # zi from the past inputs and outputs so a model change continues the recursion
        zi = ss.lfiltic(bb, a, self.y_hist, self.e_hist) if self.p or self.q else None
        y, _ = ss.lfilter(bb, a, e, zi=zi)
        self.y_hist = np.concatenate([y[::-1], self.y_hist])[: self.p]
        self.e_hist = np.concatenate([e[::-1], self.e_hist])[: self.q]
        return y


def write_penn(path: str | Path, ms: PennModelSet) -> Path:
    """A model set in the toolkit's schema and element order (``CreateResampledModels.m``)."""
    root = ET.Element("modelSet")

    def add(parent: ET.Element, tag: str, text: object) -> None:
        ET.SubElement(parent, tag).text = str(text)

    def add_list(parent: ET.Element, tag: str, vals: Array) -> None:
        e = ET.SubElement(parent, tag)
        for v in vals:
            add(e, "value", repr(float(v)) if not isinstance(v, np.integer) else int(v))

    mu = 0.0 if ms.mu is None or not np.isfinite(ms.mu) else ms.mu
    for tag, text in (("material", ms.name), ("AccelUnits", "m/s^2"), ("SpeedUnits", "mm/s"),
                      ("ForceUnits", "N"), ("SampleRate", ms.fs_hz), ("mu", mu),
                      ("numMod", len(ms.speeds_mm_s)), ("numTri", len(ms.tri)),
                      ("maxSpeed", ms.max_speed_mm_s), ("maxForce", ms.max_force_n)):
        add(root, tag, text)
    add_list(root, "speedList", ms.speeds_mm_s)
    add_list(root, "forceList", ms.forces_n)
    for t in ms.tri + 1:
        add_list(root, "tri", t)
    add(root, "numARCoeff", ms.ar_lsf.shape[1])
    add(root, "numMACoeff", ms.ma_lsf.shape[1])
    for i in range(len(ms.speeds_mm_s)):
        m = ET.SubElement(root, "model")
        add(m, "modNum", i + 1)
        add_list(m, "ARcoeff", lsf_to_poly(ms.ar_lsf[i]))
        add_list(m, "ARlsf", ms.ar_lsf[i])
        add_list(m, "MAcoeff", lsf_to_poly(ms.ma_lsf[i]) if ms.ma_lsf.shape[1] else [1.0])
        add_list(m, "MAlsf", ms.ma_lsf[i])
        for tag, vals in (("var", ms.var), ("gain", ms.gain), ("speedMod", ms.speeds_mm_s),
                          ("forceMod", ms.forces_n)):
            add(m, tag, vals[i])
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return Path(path)
