"""Penn Haptic Texture Toolkit (HaTT) model files: ARMA models over speed and force.

A ``Models_<material>.xml`` (Culbertson, Lopez Delgado and Kuchenbecker 2014) is a
``<modelSet>``: ``SampleRate``, ``maxSpeed`` (mm/s), ``maxForce`` (N), ``speedList``/
``forceList``, the Delaunay triangles ``<tri>`` (MATLAB's 1-based indices into those
lists), ``numARCoeff``, ``numMACoeff``, and one ``<model>`` per point with ``ARlsf``,
``MAlsf``, ``var``, ``gain``, ``speedMod``, ``forceMod``; as the toolkit's
``CreateResampledModels.m`` writes and ``AutoGenHashMatrix`` reads it. Its synthesis
(``LPCvibration``), in m/s^2 at the model rate:

    y(k) = -sum_i A_i y(k-i) + gain * (e(k) + sum_j B_j e(k-j)),  e ~ N(0, var)

(AR files, ``numMACoeff`` 0: no ``gain``, no B), with the LSFs, ``var`` and ``gain``
interpolated by barycentric weights in the triangle holding (speed, force).
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError

Array = NDArray[np.float64]
DEFAULT_FS_HZ = 10_000.0
#: Unit spellings the reader accepts (lower case, spaces removed); the toolkit's HTML
#: shows m/s^2, mm/s and N.
_UNITS = {"AccelUnits": ("m/s^2", "m/s2", "m/s/s", "m/sec^2"),
          "SpeedUnits": ("mm/s", "mm/sec"), "ForceUnits": ("n", "newton", "newtons")}


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
    text = (root.findtext(key) or "").strip()
    if not text:
        if default is not None:
            return default
        raise UserError(f"{where}: missing element <{key}>")
    try:
        return float(text)
    except ValueError:
        raise UserError(f"{where}: <{key}> is not a number ({text!r})") from None


def _count(root: ET.Element, key: str, where: str, default: int | None = None) -> int:
    """A count element (numARCoeff, numMod, ...): a whole number >= 0."""
    v = _num(root, key, where, default)
    if not (math.isfinite(v) and v >= 0 and v == round(v)):
        raise UserError(f"{where}: <{key}> is not a whole number >= 0 ({v:g})")
    return int(v)


def _check_units(root: ET.Element, where: str) -> None:
    for key, ok in _UNITS.items():
        text = (root.findtext(key) or "").strip()
        if text and "".join(text.split()).lower() not in ok:
            warnings.warn(f"{where}: <{key}> is {text!r}; read as {ok[0]} (the toolkit's unit)",
                          stacklevel=3)


def _lsf(m: ET.Element, tag: str, count_tag: str, size: int, where: str) -> Array:
    """``size`` LSFs sorted within [0, pi] (what the toolkit's LSF-to-polynomial assumes)."""
    # numMACoeff 0: the toolkit does not read <MAlsf>.
    lsf = _values(m.find(tag), f"{where}: <{tag}>") if size or tag == "ARlsf" else np.zeros(0)
    if lsf.size != size:
        raise UserError(f"{where}: <{tag}> has {lsf.size} values, <{count_tag}> says {size}")
    if lsf.size and (lsf[0] < 0 or lsf[-1] > np.pi or np.any(np.diff(lsf) < 0)):
        raise UserError(f"{where}: <{tag}>: not sorted line spectral frequencies in [0, pi] rad")
    return lsf


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
    _check_units(root, w)
    p = _count(root, "numARCoeff", w)
    q = _count(root, "numMACoeff", w, 0)
    fs = _num(root, "SampleRate", w, DEFAULT_FS_HZ)
    if not 0 < fs < math.inf:
        raise UserError(f"{w}: <SampleRate> must be a positive finite rate, got {fs:g}")
    models = root.findall("model")
    if not models:
        raise UserError(f"{w}: no <model> elements")
    n = len(models)
    num_mod = _count(root, "numMod", w, n)
    if num_mod != n:
        raise UserError(f"{w}: <numMod> says {num_mod}, the file has {n} <model> elements")
    sp, fo, ar, ma, var, gain = [], [], [], [], [], []
    for i, m in enumerate(models):
        mw = f"{w}: model {i + 1}"
        sp.append(_num(m, "speedMod", mw))
        fo.append(_num(m, "forceMod", mw))
        var.append(_num(m, "var", mw))
        if not var[-1] >= 0:
            raise UserError(f"{mw}: <var> must be >= 0, got {var[-1]:g}")
        # AR models (numMACoeff 0): the toolkit reads no gain.
        gain.append(_num(m, "gain", mw, 1.0) if q else 1.0)
        ar.append(_lsf(m, "ARlsf", "numARCoeff", p, mw))
        ma.append(_lsf(m, "MAlsf", "numMACoeff", q, mw))
    speeds, forces = np.asarray(sp), np.asarray(fo)
    order = _list_order(root, speeds, forces, w)
    tri = _read_tri(root, n, w)
    return PennModelSet(
        name=(root.findtext("material") or "").strip() or path.stem, fs_hz=fs,
        speeds_mm_s=speeds[order], forces_n=forces[order], tri=tri,
        ar_lsf=np.vstack(ar)[order], ma_lsf=np.vstack(ma)[order],
        var=np.asarray(var)[order], gain=np.asarray(gain)[order],
        max_speed_mm_s=_num(root, "maxSpeed", w, float(speeds.max())),
        max_force_n=_num(root, "maxForce", w, float(forces.max())),
        mu=_num(root, "mu", w, float("nan")),
    )


def _list_order(root: ET.Element, speeds: Array, forces: Array, w: str) -> NDArray[np.int64]:
    """The model for each entry of speedList/forceList: the toolkit stores a model at the
    list position with its (speed, force), and ``<tri>`` indexes that list."""
    n = speeds.size
    if root.find("speedList") is None and root.find("forceList") is None:
        return np.arange(n)
    ls = _values(root.find("speedList"), f"{w}: <speedList>")
    lf = _values(root.find("forceList"), f"{w}: <forceList>")
    if ls.size != n or lf.size != n:
        raise UserError(f"{w}: <speedList> and <forceList> have {ls.size} and {lf.size} "
                        f"values for {n} models")
    order = np.empty(n, np.int64)
    for k in range(n):
        hit = np.flatnonzero(np.isclose(speeds, ls[k], rtol=1e-6, atol=1e-6)
                             & np.isclose(forces, lf[k], rtol=1e-6, atol=1e-6))
        if hit.size == 0:
            raise UserError(f"{w}: <speedList>/<forceList> value {k + 1} ({ls[k]:g} mm/s, "
                            f"{lf[k]:g} N) has no <model> with that speedMod and forceMod")
        order[k] = hit[0]
    return order


def _read_tri(root: ET.Element, n: int, w: str) -> NDArray[np.int64]:
    """The triangles, 0-based; the file's indices are MATLAB's 1-based ones."""
    rows = []
    for k, t in enumerate(root.findall("tri")):
        v = _values(t, f"{w}: <tri> {k + 1}")
        if v.size != 3:
            raise UserError(f"{w}: <tri> {k + 1} has {v.size} values, expected 3")
        bad = v[(v < 1) | (v > n) | (v != np.round(v))]
        if bad.size:
            raise UserError(f"{w}: <tri> {k + 1}: index {bad[0]:g} outside 1..{n}")
        rows.append(v.astype(np.int64) - 1)
    num_tri = _count(root, "numTri", w, len(rows))  # absent or empty: not checked
    if num_tri != len(rows):
        raise UserError(f"{w}: <numTri> says {num_tri}, the file has "
                        f"{len(rows)} <tri> elements")
    return np.vstack(rows) if rows else np.zeros((0, 3), np.int64)


def barycentric_weights(ms: PennModelSet, speed_mm_s: Array, force_n: Array) -> Array:
    """(k, m) weights of the m models at k (speed, force) points: barycentric in the first
    Delaunay triangle holding the point; outside every triangle the nearest model alone
    (the toolkit's walk is undefined outside the hull: it prints "Unstable!"). Points are
    clamped into [0, maxSpeed] x [0, maxForce] (NaN: 0), as the toolkit's ``HashAndInterp2``."""
    s = np.clip(np.nan_to_num(np.atleast_1d(speed_mm_s).astype(float)), 0.0, ms.max_speed_mm_s)
    f = np.clip(np.nan_to_num(np.atleast_1d(force_n).astype(float)), 0.0, ms.max_force_n)
    k, m = s.size, ms.speeds_mm_s.size
    out = np.zeros((k, m))
    todo = np.ones(k, bool)
    pts = np.column_stack([ms.speeds_mm_s, ms.forces_n])
    for t in ms.tri:
        if not todo.any():
            break
        p0, p1, p2 = pts[t]
        mat = np.column_stack([p1 - p0, p2 - p0])
        if abs(np.linalg.det(mat)) < 1e-12:
            continue
        l12 = np.linalg.solve(mat, np.vstack([s - p0[0], f - p0[1]]))
        wt = np.vstack([1.0 - l12[0] - l12[1], l12[0], l12[1]])
        inside = todo & np.all(wt >= -1e-9, axis=0)
        wi = np.clip(wt[:, inside], 0.0, 1.0)
        out[np.flatnonzero(inside)[:, None], t] = (wi / wi.sum(axis=0)).T
        todo &= ~inside
    if todo.any():
        rows = np.flatnonzero(todo)
        d = np.hypot(ms.speeds_mm_s[None, :] - s[rows, None], ms.forces_n[None, :] - f[rows, None])
        out[rows, np.argmin(d, axis=1)] = 1.0
    return out
