"""Penn Haptic Texture Toolkit (HaTT) model files: ARMA models over speed and force.

A HaTT XML file (one per texture; Culbertson, Lopez Delgado and Kuchenbecker 2014) is
a ``<modelSet>`` with ``numMod``, ``numTri``, ``maxSpeed`` (mm/s), ``maxForce`` (N),
``speedList``/``forceList`` (``<value>`` lists), a Delaunay triangulation of the
(speed, force) points as ``<tri><value>i</value>x3</tri>`` (1-based in the toolkit's
files), ``numARCoeff``, ``numMACoeff``, optional ``SampleRate`` (Hz) and ``mu``, then one
``<model>`` per point with ``speedMod``, ``forceMod``, ``var``, ``gain`` (ARMA only),
``ARlsf`` and ``MAlsf`` (radians) and optionally ``ARcoeff``/``MAcoeff``.

Synthesis (the toolkit's convention), at the model's sample rate:

    y(k) = -sum_i A_i y(k-i) + gain * (e(k) + sum_j B_j e(k-j)),  e ~ N(0, var)

which is eq. 5 extended with the moving-average part. Models are interpolated inside
the Delaunay triangle holding (speed, force) by barycentric weights on the LSFs (stable),
``var`` and ``gain``. The toolkit's files are not shipped; point the reader at yours.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.lsf import lsf_to_poly

Array = NDArray[np.float64]
DEFAULT_FS_HZ = 10_000.0


@dataclass
class PennModelSet:
    name: str
    fs_hz: float
    speeds_mm_s: Array  # (m,)
    forces_n: Array  # (m,)
    tri: NDArray[np.int64]  # (t, 3) 0-based
    ar_lsf: Array  # (m, p)
    ma_lsf: Array  # (m, q)
    var: Array
    gain: Array
    max_speed_mm_s: float
    max_force_n: float
    mu: float | None = None


def _values(node: ET.Element | None, where: str) -> Array:
    if node is None:
        raise UserError(f"{where}: missing")
    try:
        return np.array([float(v.text or "") for v in node.findall("value")])
    except ValueError as exc:
        raise UserError(f"{where}: {exc}") from None


def _num(root: ET.Element, key: str, where: str, default: float | None = None) -> float:
    node = root.find(key)
    if node is None or node.text is None:
        if default is not None:
            return default
        raise UserError(f"{where}: missing element <{key}>")
    try:
        return float(node.text)
    except ValueError:
        raise UserError(f"{where}: <{key}> is not a number ({node.text!r})") from None


def read_penn(path: str | Path) -> PennModelSet:
    """Parse a HaTT model XML file; errors name the file and element."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise UserError(f"{path}: missing") from None
    except ET.ParseError as exc:
        raise UserError(f"{path}: not XML ({exc})") from None
    if root.tag != "modelSet":
        raise UserError(f"{path}: root element is <{root.tag}>, expected <modelSet>")
    w = str(path)
    p = int(_num(root, "numARCoeff", w))
    q = int(_num(root, "numMACoeff", w, 0.0))
    fs = _num(root, "SampleRate", w, DEFAULT_FS_HZ)
    models = root.findall("model")
    if not models:
        raise UserError(f"{w}: no <model> elements")
    sp, fo, ar, ma, var, gain = [], [], [], [], [], []
    for i, m in enumerate(models):
        mw = f"{w}: model {i + 1}"
        sp.append(_num(m, "speedMod", mw))
        fo.append(_num(m, "forceMod", mw))
        var.append(_num(m, "var", mw))
        gain.append(_num(m, "gain", mw, 1.0))
        a = _values(m.find("ARlsf"), f"{mw}: <ARlsf>")
        if a.size != p:
            raise UserError(f"{mw}: <ARlsf> has {a.size} values, <numARCoeff> says {p}")
        ar.append(a)
        b = _values(m.find("MAlsf"), f"{mw}: <MAlsf>") if q else np.zeros(0)
        if b.size != q:
            raise UserError(f"{mw}: <MAlsf> has {b.size} values, <numMACoeff> says {q}")
        ma.append(b)
    tris = [_values(t, f"{w}: <tri>").astype(np.int64) for t in root.findall("tri")]
    n = len(models)
    if tris:
        tri = np.vstack(tris)
        if tri.shape[1] != 3:
            raise UserError(f"{w}: <tri> must hold 3 values")
        if tri.min() >= 1 and tri.max() == n:  # the toolkit writes MATLAB's 1-based indices
            tri = tri - 1
        if tri.min() < 0 or tri.max() >= n:
            raise UserError(f"{w}: <tri> indices outside 1..{n}")
    else:
        tri = np.zeros((0, 3), np.int64)
    speeds = np.asarray(sp)
    forces = np.asarray(fo)
    return PennModelSet(
        name=path.stem, fs_hz=fs, speeds_mm_s=speeds, forces_n=forces, tri=tri,
        ar_lsf=np.vstack(ar), ma_lsf=np.vstack(ma) if q else np.zeros((n, 0)),
        var=np.asarray(var), gain=np.asarray(gain),
        max_speed_mm_s=_num(root, "maxSpeed", w, float(speeds.max())),
        max_force_n=_num(root, "maxForce", w, float(forces.max())),
        mu=_num(root, "mu", w, float("nan")),
    )


def write_penn(path: str | Path, ms: PennModelSet) -> Path:
    """Write a model set in the toolkit's schema (for tests and hand-made models)."""
    root = ET.Element("modelSet")

    def add(parent: ET.Element, tag: str, text: object) -> ET.Element:
        e = ET.SubElement(parent, tag)
        e.text = str(text)
        return e

    def add_list(parent: ET.Element, tag: str, vals: Array) -> None:
        e = ET.SubElement(parent, tag)
        for v in vals:
            add(e, "value", repr(float(v)) if not isinstance(v, np.integer) else int(v))

    add(root, "material", ms.name)
    add(root, "mu", 0.0 if ms.mu is None or not np.isfinite(ms.mu) else ms.mu)
    add(root, "SampleRate", ms.fs_hz)
    add(root, "numMod", len(ms.speeds_mm_s))
    add(root, "numTri", len(ms.tri))
    add(root, "maxSpeed", ms.max_speed_mm_s)
    add(root, "maxForce", ms.max_force_n)
    add_list(root, "speedList", ms.speeds_mm_s)
    add_list(root, "forceList", ms.forces_n)
    for t in ms.tri + 1:
        add_list(root, "tri", t)
    add(root, "numARCoeff", ms.ar_lsf.shape[1])
    add(root, "numMACoeff", ms.ma_lsf.shape[1])
    for i in range(len(ms.speeds_mm_s)):
        m = ET.SubElement(root, "model")
        add(m, "modelNum", i + 1)
        add(m, "speedMod", ms.speeds_mm_s[i])
        add(m, "forceMod", ms.forces_n[i])
        add(m, "var", ms.var[i])
        add(m, "gain", ms.gain[i])
        add_list(m, "ARlsf", ms.ar_lsf[i])
        add_list(m, "ARcoeff", lsf_to_poly(ms.ar_lsf[i])[1:])
        if ms.ma_lsf.shape[1]:
            add_list(m, "MAlsf", ms.ma_lsf[i])
            add_list(m, "MAcoeff", lsf_to_poly(ms.ma_lsf[i])[1:])
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return Path(path)


def barycentric(ms: PennModelSet, speed_mm_s: float, force_n: float) -> tuple[NDArray, Array]:
    """Vertex indices and weights of the triangle holding the point (clamped to the grid).

    Outside every triangle, the nearest model alone (weight 1), as the toolkit does at
    the edges of its measured range.
    """
    s = min(max(speed_mm_s, 0.0), ms.max_speed_mm_s)
    f = min(max(force_n, 0.0), ms.max_force_n)
    pts = np.column_stack([ms.speeds_mm_s, ms.forces_n])
    for t in ms.tri:
        p0, p1, p2 = pts[t]
        m = np.column_stack([p1 - p0, p2 - p0])
        det = np.linalg.det(m)
        if abs(det) < 1e-12:
            continue
        l1, l2 = np.linalg.solve(m, np.array([s, f]) - p0)
        w = np.array([1.0 - l1 - l2, l1, l2])
        if np.all(w >= -1e-9):
            return t, np.clip(w, 0.0, 1.0) / np.clip(w, 0.0, 1.0).sum()
    j = int(np.argmin(np.hypot(ms.speeds_mm_s - s, ms.forces_n - f)))
    return np.array([j]), np.array([1.0])


def interpolate(ms: PennModelSet, speed_mm_s: float, force_n: float
                ) -> tuple[Array, Array, float, float]:
    """(A, B, var, gain) at (speed, force): LSFs, var and gain weighted barycentrically."""
    idx, w = barycentric(ms, speed_mm_s, force_n)
    a = lsf_to_poly(w @ ms.ar_lsf[idx])
    b = lsf_to_poly(w @ ms.ma_lsf[idx]) if ms.ma_lsf.shape[1] else np.array([1.0])
    return a, b, float(w @ ms.var[idx]), float(w @ ms.gain[idx])


class PennRenderer:
    """The ARMA synthesis at the model rate, state carried across blocks and models."""

    def __init__(self, ms: PennModelSet, seed: int | None = None):
        self.ms = ms
        self.rng = np.random.default_rng(seed)
        self.p = ms.ar_lsf.shape[1]
        self.q = ms.ma_lsf.shape[1]
        self.y_hist = np.zeros(self.p)  # newest first
        self.e_hist = np.zeros(self.q)

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

    def render(self, speed_mm_s: float, force_n: float, seconds: float,
               fs_out_hz: float = 1000.0, block_s: float = 0.01) -> Array:
        """``seconds`` of output resampled (anti-aliased) to ``fs_out_hz``."""
        n = round(seconds * self.ms.fs_hz)
        step = max(1, round(block_s * self.ms.fs_hz))
        y = np.concatenate([self.block(speed_mm_s, force_n, min(step, n - k))
                            for k in range(0, n, step)]) if n else np.zeros(0)
        if abs(fs_out_hz - self.ms.fs_hz) < 1e-9:
            return y
        from fractions import Fraction

        fr = Fraction(fs_out_hz / self.ms.fs_hz).limit_denominator(1000)
        return ss.resample_poly(y, fr.numerator, fr.denominator)
