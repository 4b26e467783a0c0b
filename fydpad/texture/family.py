"""The texture-family contract every family (LPC, HaTT, friction, grating, MLP) meets,
and the finger stream it renders from.

Every family takes one speed input, ``speed_mm_s``: the finger's speed along the surface
(the centroid's speed low-passed at 10 Hz, Bianchi 2015 III-B). ``render`` takes a whole
:class:`FingerBlock` (the ``fydpad texture`` commands); ``tick`` is one step of the
station's 1 kHz loop after ``prepare(rate_hz)``. A :class:`Kind` tells the registry
(:mod:`fydpad.texture.families`) how to read and fit one family's model files.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad.errors import UserError, read_json

Array = NDArray[np.float64]
#: ``"format"`` of every texture model file.
FORMAT = "fydpad-texture-model"
#: The finger inputs a family may need ("force_change": only the force's change, so a
#: constant force of any value renders the same).
INPUTS = ("speed_mm_s", "x_mm", "y_mm", "force_n", "force_change")


class RateMismatch(UserError, ValueError):
    """A finger block at another rate than the only one a model renders at: the message
    names the model's key, the caller the block's source."""


@dataclass(frozen=True)
class FingerBlock:
    """The finger state stream as equal-length arrays at one sample rate ``fs_hz``."""

    fs_hz: float
    t_s: Array
    contact: NDArray[np.bool_]
    x_mm: Array
    y_mm: Array
    speed_mm_s: Array
    force_n: Array

    def __post_init__(self) -> None:
        n = self.t_s.shape[0]
        for name, a in (("contact", self.contact), ("x_mm", self.x_mm), ("y_mm", self.y_mm),
                        ("speed_mm_s", self.speed_mm_s), ("force_n", self.force_n)):
            if a.shape != (n,):
                raise ValueError(f"FingerBlock.{name} must have shape ({n},), got {a.shape}")


@dataclass(frozen=True)
class Kind:
    """One family in the registry: how to build it from a parsed model file, fit one from
    scans, or (HaTT) read its own file format. ``fydpad texture fit`` calls, for every
    family, ``check_options``, ``notes``, ``fit``, ``describe`` and ``plot`` in turn."""

    name: str
    from_json: Callable[[dict[str, Any], str], TextureFamily]
    #: ``fit(scans, **options)`` -> the model file's JSON.
    fit: Callable[..., dict[str, Any]] | None
    from_file: Callable[[str], TextureFamily] | None = None
    #: The ``fydpad texture fit`` options it takes (argument names), passed to ``fit``;
    #: ``report`` among them: a callable the fit hands the lines of how it chose.
    fit_options: tuple[str, ...] = ()
    #: Whether ``fit`` takes options beyond those (``--set KEY=VALUE``).
    set_options: bool = True
    #: ``check_options(options, fs_hz)``: a UserError for an option the scans' rate rules
    #: out, before the fit.
    check_options: Callable[[dict[str, Any], float], None] | None = None
    #: ``notes(scans, options)``: warnings about the scans as a whole.
    notes: Callable[[list, dict[str, Any]], list[str]] | None = None
    #: ``describe(data, where)``: the lines ``fydpad texture fit`` prints about a fit.
    describe: Callable[[dict[str, Any], str], list[str]] | None = None
    #: ``plot(path, scans, data, options)``: a figure of the fit against the scans.
    plot: Callable[[str, list, dict[str, Any], dict[str, Any]], None] | None = None
    #: ``compare_options(scans)``: the fit options ``texture compare`` uses for one
    #: surface's scans (a quick fit: many surfaces, one model each).
    compare_options: Callable[[list], dict[str, Any]] | None = None
    #: (channel rendered, band compared in Hz, the scan's observable) of the "shape"
    #: distance; None: the vibration against the acceleration (``evaluation.identify``).
    observable: tuple[str, tuple[float, float], str] | None = None
    #: ``identify``'s default distance: "shape" (levels and tilt removed: families whose
    #: level is a gain) or "bands" (third-octave levels: models of recorded accelerations).
    distance: str = "shape"
    #: The name users know the family by, in messages ("HaTT"); the kind's name if empty.
    title: str = ""


class TextureFamily:
    """A fitted texture model of one family, ready to render: the contract, with the
    defaults of a family without parameters, counters or speed gaps. A family sets
    ``kind`` (its name in files and specs), ``channels`` (output channel -> native rate
    in Hz), ``tick_channels`` (what ``tick`` returns, in order) and ``needs`` (a subset
    of :data:`INPUTS`), and implements ``render``, ``tick`` and ``reset``."""

    kind: str
    channels: dict[str, float]
    tick_channels: tuple[str, ...]
    needs: frozenset[str]
    #: The surface the model was fitted on ("" when unknown).
    surface = ""
    #: Where a stroke starts (mm; a position-indexed model's own origin).
    x0_mm = 0.0
    #: The high-pass (Hz) a recording is compared through (the fit's, for LPC).
    highpass_hz = 10.0

    def __init__(self) -> None:
        #: Render parameters and their current values (``set_parameter``).
        self.parameters: dict[str, Any] = {}

    def set_parameter(self, name: str, value: Any) -> None:
        """Set a render parameter; UserError for a name not in ``parameters``."""
        if name not in self.parameters:
            raise UserError(f"a {self.kind} model has no render parameter {name!r} "
                            f"(it has: {', '.join(self.parameters) or 'none'})")
        self.parameters[name] = value

    def check_rate(self, rate_hz: float) -> None:
        """A UserError naming its file when it cannot tick at ``rate_hz``."""

    def prepare(self, rate_hz: float) -> None:
        """``check_rate`` and build the tick path, before the station's loop starts."""
        self.check_rate(rate_hz)

    def render(self, finger: FingerBlock, channel: str) -> Array:
        """The signal on ``channel`` for the whole block (sampled at ``finger.fs_hz``)."""
        raise NotImplementedError

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float, ...]:
        """One render-loop step (no allocation): the values of ``tick_channels``."""
        raise NotImplementedError

    def reset(self) -> None:
        """Forget the signal history (a new stroke)."""
        raise NotImplementedError

    def counters(self) -> dict[str, int]:
        """Events counted while rendering (the LPC limiter's ``limiter_resets``)."""
        return {}

    def covers(self, speed_mm_s: Array) -> NDArray[np.bool_]:
        """The samples whose speed the model renders from its data (evaluation compares
        the recording there)."""
        return np.asarray(speed_mm_s, float) > 1.0

    def unscanned_speeds(self) -> list[tuple[float, float]] | None:
        """Speed spans (mm/s) no scan of its fit went at (it interpolates there); None
        when its file does not record them."""
        return []

    def check_channel(self, channel: str) -> None:
        if channel not in self.channels:
            raise UserError(f"a {self.kind} model renders {', '.join(self.channels)}; "
                            f"not {channel!r}")


#: The name the families subclass.
FamilyBase = TextureFamily


class TickPosition:
    """The finger's x between camera frames (~30 Hz) for position-indexed families at
    1 kHz: a new centroid (a change of value) is stamped with the tick time, and between
    frames x is extrapolated along the velocity over the last ``frames`` frames (a longer
    base shrinks the 1-tick stamping jitter) for at most ``hold_s``; a centroid unchanged
    for ``stop_s`` is a finger at rest. No allocation."""

    def __init__(self, hold_s: float = 0.1, frames: int = 3, stop_s: float = 0.25) -> None:
        self.hold_s = hold_s
        self.stop_s = stop_s
        self.frames = frames
        self._ts = [0.0] * (frames + 1)
        self._xs = [0.0] * (frames + 1)
        self.reset()

    def reset(self) -> None:
        self._x = self._t = self._v = float("nan")
        self._n = 0

    def update(self, t_s: float, contact: bool, x_mm: float) -> float:
        """The estimated x (mm) now; NaN without contact."""
        if not contact or x_mm != x_mm:
            self.reset()
            return float("nan")
        if x_mm != self._x:
            m = self.frames + 1
            k = self._n % m
            self._ts[k], self._xs[k] = t_s, x_mm
            self._n += 1
            if self._n >= 2:
                back = min(self._n - 1, self.frames)
                j = (self._n - 1 - back) % m
                if t_s > self._ts[j]:
                    self._v = (x_mm - self._xs[j]) / (t_s - self._ts[j])
            self._x, self._t = x_mm, t_s
        dt = t_s - self._t
        if dt >= self.stop_s:
            self._v = 0.0  # no new centroid for a while: the finger has stopped
        return x_mm + (self._v * min(dt, self.hold_s) if self._v == self._v else 0.0)


def hold_finite(x: Array, first: float) -> Array:
    """``x`` with every non-finite sample replaced by the last finite one before it
    (``first`` before any): a missing load-cell reading holds the last one."""
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    if ok.all():
        return x
    idx = np.where(ok, np.arange(x.size), -1)
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx >= 0, x[np.maximum(idx, 0)], first)


def runs(mask: ArrayLike, min_len: int = 1) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of ``mask`` at least ``min_len`` long."""
    m = np.asarray(mask, bool).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], m, [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2], strict=True)
            if b - a >= min_len]


def mixed_surfaces(scans: list, options: dict[str, Any]) -> list[str]:
    """A note when scans of several surfaces (``# surface=``) are pooled unnamed."""
    labels = [sc.meta.get("surface") for sc in scans]
    if options.get("surface") is not None or None in labels or len(set(labels)) < 2:
        return []
    counts = ", ".join(f"{s} ({labels.count(s)})" for s in dict.fromkeys(labels))
    return [f"the scans are of {len(set(labels))} surfaces (# surface=: {counts}), pooled "
            f"into one model labelled {labels[0]}; fit each surface on its own, or name the "
            "mix with --surface"]


# ------------------------------------------------------------------ finger streams
def finger_from_scan(scan: Any) -> FingerBlock:
    """The finger stream of a scan (contact throughout; x from ``x_mm`` or the speed;
    force from ``force_n`` or 1 N)."""
    n = scan.t_s.size
    x = scan.x_mm if scan.x_mm is not None else np.cumsum(scan.speed_mm_s) / scan.fs_hz
    force = scan.force_n if scan.force_n is not None else np.ones(n)
    return FingerBlock(scan.fs_hz, np.asarray(scan.t_s, float), np.ones(n, bool),
                       np.asarray(x, float), np.zeros(n), np.asarray(scan.speed_mm_s, float),
                       np.asarray(force, float))


def resample_finger(finger: FingerBlock, fs_hz: float) -> FingerBlock:
    """The finger stream at another rate (linear interpolation; contact: nearest)."""
    t = np.arange(round((finger.t_s[-1] - finger.t_s[0]) * fs_hz) + 1) / fs_hz + finger.t_s[0]

    def lin(a: Array) -> Array:
        return np.interp(t, finger.t_s, a)

    k = np.clip(np.searchsorted(finger.t_s, t), 0, finger.t_s.size - 1)
    return FingerBlock(fs_hz, t, finger.contact[k], lin(finger.x_mm), lin(finger.y_mm),
                       lin(finger.speed_mm_s), lin(finger.force_n))


def constant_stroke(speed_mm_s: float, seconds: float, fs_hz: float, x0_mm: float = 0.0,
                    force_n: float = 1.0) -> FingerBlock:
    """A finger at a constant speed along +x, in contact (``fydpad texture synth``)."""
    n = round(seconds * fs_hz)
    t = np.arange(n) / fs_hz
    return FingerBlock(fs_hz, t, np.ones(n, bool), x0_mm + speed_mm_s * t, np.zeros(n),
                       np.full(n, float(speed_mm_s)), np.full(n, float(force_n)))


# ------------------------------------------------------------------ model files
def read_model_json(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    data = read_json(path, "JSON model")
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise UserError(f"{path}: not a fydpad texture model (key 'format' must be '{FORMAT}')")
    return data


def save_model_json(data: dict[str, Any], path: str | Path) -> Path:
    """Strict JSON (no NaN or Infinity): a non-finite number is a UserError naming it."""
    path = Path(path)
    try:
        text = json.dumps(data, indent=1, allow_nan=False)
    except ValueError:
        raise UserError(f"{path}: the model holds a non-finite number; not written") from None
    path.write_text(text + "\n", encoding="utf-8")
    return path


def require(d: Any, key: str, where: str, kind: type | tuple[type, ...] = (int, float)) -> Any:
    """``d[key]`` checked for type; a UserError names the file and the key otherwise."""
    if not isinstance(d, dict) or key not in d:
        raise UserError(f"{where}: missing key '{key}'")
    v = d[key]
    if not isinstance(v, kind) or (isinstance(v, bool) and kind is not bool):
        raise UserError(f"{where}: key '{key}' has the wrong type ({type(v).__name__})")
    if isinstance(v, float) and not math.isfinite(v):
        raise UserError(f"{where}: key '{key}' is not a finite number")
    return v


def section(data: dict[str, Any], key: str, where: str) -> dict[str, Any]:
    """The optional object ``data[key]`` ({} when absent); a UserError otherwise."""
    d = data.get(key, {})
    if not isinstance(d, dict):
        raise UserError(f"{where}: key '{key}' must be an object ({{...}})")
    return d


def optional(d: dict[str, Any], key: str, where: str, default: float,
             positive: bool = False) -> float:
    """``d[key]`` as :func:`require` checks it (``positive``: also > 0), ``default`` when
    absent."""
    if key not in d:
        return default
    v = float(require(d, key, where))
    if positive and not v > 0:
        raise UserError(f"{where}: key '{key}' must be positive")
    return v


def require_version(data: dict[str, Any], where: str, kind: str, version: int) -> None:
    if data.get("kind") != kind:
        raise UserError(f"{where}: key 'kind' is {data.get('kind')!r}, expected {kind!r}")
    if data.get("format_version") != version:
        raise UserError(f"{where}: key 'format_version' is {data.get('format_version')!r}; "
                        f"this fydpad reads {kind} models of version {version} only")
