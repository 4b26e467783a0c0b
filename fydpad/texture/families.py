"""The texture-family registry (issue 9): load, fit and select models of every family.

A model file is JSON with ``"format": "fydpad-texture-model"`` and ``"kind"`` naming
its family; an LPC file without ``"kind"`` is ``lpc`` (files written before issue 9).
A spec is ``MODEL.json`` or ``KIND:MODEL.json`` (the kind then must match the file's).

Registering a family (the MLP module does this)::

    from fydpad.texture.families import Kind, register_kind

    register_kind(Kind(
        name="mlp",
        from_json=lambda data, where: MlpFamily(parse_mlp(data, where)),  # -> TextureFamily
        fit=fit_mlp_json,  # (scans: list[Scan], **options) -> model JSON dict with "kind"
        summary="3-10-1 network from (v_x, v_y, delta f) to the normal acceleration",
    ))

at import of the family's module, and list that module in ``_LAZY`` below so that
``load_family``/``fit_family`` import it on first use. ``from_json`` must raise
:class:`fydpad.errors.UserError` naming ``where`` (the file) and the key at fault.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fydpad.errors import UserError, read_json
from fydpad.texture.family import Array, FingerBlock, TextureFamily, TickPosition

FORMAT = "fydpad-texture-model"


@dataclass(frozen=True)
class Kind:
    """One family: how to build it from a parsed model file, and how to fit one."""

    name: str
    from_json: Callable[[dict[str, Any], str], TextureFamily]
    fit: Callable[..., dict[str, Any]] | None
    summary: str = ""
    #: A family read from its own file format instead of JSON (penn: HaTT XML).
    from_file: Callable[[str], TextureFamily] | None = None


KINDS: dict[str, Kind] = {}
#: Families registered by importing their module on first use.
_LAZY = {"lpc": "fydpad.texture.families", "friction": "fydpad.texture.friction",
         "grating": "fydpad.texture.grating", "mlp": "fydpad.texture.mlp",
         "mlp_lsf": "fydpad.texture.mlp", "penn": "fydpad.texture.penn_family"}
#: The kinds the commands offer.
KIND_NAMES = tuple(_LAZY)
#: Kinds read from another tool's files (HaTT XML), never fitted here.
IMPORTED_KINDS = ("penn",)
#: The kinds ``fydpad texture fit`` and ``compare`` fit from scans.
FIT_KIND_NAMES = tuple(k for k in KIND_NAMES if k not in IMPORTED_KINDS)


def register_kind(kind: Kind) -> None:
    KINDS[kind.name] = kind


def get_kind(name: str) -> Kind:
    if name not in KINDS and name in _LAZY:
        importlib.import_module(_LAZY[name])  # a family that fails to import is a bug
    if name not in KINDS:
        raise UserError(f"unknown texture kind {name!r} (known: {', '.join(sorted(_LAZY))})")
    return KINDS[name]


def split_spec(spec: str) -> tuple[str | None, str]:
    """``KIND:PATH`` -> (KIND, PATH); a bare path -> (None, PATH)."""
    head, sep, tail = spec.partition(":")
    if sep and head in _LAZY | KINDS.keys():
        return head, tail
    return None, spec


def read_model_json(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    data = read_json(path, "JSON model")
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise UserError(f"{path}: not a fydpad texture model (key 'format' must be '{FORMAT}')")
    return data


def model_kind(data: dict[str, Any]) -> str:
    """The family of a parsed model file (no ``kind``: the LPC format of issue 4)."""
    return str(data.get("kind", "lpc"))


def load_family(spec: str | Path) -> TextureFamily:
    """A ready-to-render family from ``MODEL.json`` or ``KIND:MODEL.json``."""
    want, path = split_spec(str(spec))
    own = _file_format_kind(want, path)
    if own is not None:  # not JSON: a HaTT XML file (penn:FILE.xml or FILE.xml)
        return get_kind(own).from_file(path)  # type: ignore[misc]
    data = read_model_json(path)
    kind = model_kind(data)
    if want is not None and want != kind:
        raise UserError(f"{path}: key 'kind' is {kind!r}, but the spec asked for {want!r}")
    try:
        k = get_kind(kind)
    except UserError:
        raise UserError(f"{path}: key 'kind' is {kind!r}, not a texture family (known: "
                        f"{', '.join(sorted(_LAZY))})") from None
    return k.from_json(data, str(path))


def _file_format_kind(want: str | None, path: str) -> str | None:
    """The kind of a spec whose file is not JSON: ``penn:`` or a bare ``.xml`` path."""
    if want is None and str(path).lower().endswith(".xml"):
        want = "penn"
    return want if want is not None and get_kind(want).from_file is not None else None


def spec_kind(spec: str | Path) -> str:
    """The family of ``[KIND:]MODEL`` without building it (JSON ``kind``, or penn)."""
    want, path = split_spec(str(spec))
    own = _file_format_kind(want, path)
    return own if own is not None else model_kind(read_model_json(path))


def fit_family(kind: str, scans: list, **options: Any) -> dict[str, Any]:
    """Fit a model of ``kind`` from scans; returns the model file's JSON (with ``kind``)."""
    k = get_kind(kind)
    if k.fit is None:
        raise UserError(f"texture kind {kind!r} is not fitted from scans")
    return k.fit(scans, **options)


def save_model_json(data: dict[str, Any], path: str | Path) -> Path:
    path = Path(path)
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return path


def require(d: Any, key: str, where: str, kind: type | tuple[type, ...] = (int, float)) -> Any:
    """``d[key]`` checked for type; a UserError names the file and the key otherwise."""
    if not isinstance(d, dict) or key not in d:
        raise UserError(f"{where}: missing key '{key}'")
    v = d[key]
    if not isinstance(v, kind) or (isinstance(v, bool) and kind is not bool):
        raise UserError(f"{where}: key '{key}' has the wrong type ({type(v).__name__})")
    return v


def require_version(data: dict[str, Any], where: str, kind: str, version: int) -> None:
    if data.get("kind") != kind:
        raise UserError(f"{where}: key 'kind' is {data.get('kind')!r}, expected {kind!r}")
    if data.get("format_version") != version:
        raise UserError(f"{where}: key 'format_version' is {data.get('format_version')!r}; "
                        f"this fydpad reads {kind} models of version {version} only")


# ------------------------------------------------------------------ the LPC family
class LpcFamily:
    """The FYD-pad's LPC texture (paper 004 III-B, eq. 5) behind the family interface.

    ``render`` drives :class:`~fydpad.texture.synthesis.TextureRenderer` with the
    block's speed; ``tick`` is the station's :class:`TextureSource` (speed from the
    camera centroid, output limiter) unchanged, so ``fydpad run --texture MODEL.json``
    renders exactly what it did before issue 9.
    """

    kind = "lpc"
    tick_channels = ("vibration",)

    def __init__(self, model: Any, path: str | None = None, rate_hz: float = 1000.0,
                 method: str | None = None, seed: int | None = None):
        from fydpad.texture.interpolation import DEFAULT_METHOD

        self.model = model
        self.path = path
        self.channels = {"vibration": float(model.fs_hz)}
        self.method = method or DEFAULT_METHOD
        #: The station's path band-passes through the model's drive band (--drive-filter).
        self.drive_filter = False
        self.seed = seed
        self.rate_hz = rate_hz
        self._source = None
        self._renderer = None

    def prepare(self) -> None:
        """Build the station path (it measures the limiter) before the loop starts."""
        self.source  # noqa: B018

    @property
    def source(self):
        if self._source is None:
            from fydpad.station.texture_source import TextureSource

            self._source = TextureSource(self.model, self.rate_hz, method=self.method,
                                         drive_filter=self.drive_filter)
        return self._source

    @property
    def resets(self) -> int:
        return 0 if self._source is None else self._source.resets

    def render(self, finger: FingerBlock, channel: str = "vibration") -> Array:
        from fydpad.texture.synthesis import TextureRenderer

        _check_channel(self, channel)
        if abs(finger.fs_hz - self.model.fs_hz) > 1e-6 * self.model.fs_hz:
            raise ValueError(f"LPC model renders at {self.model.fs_hz:g} Hz, the finger block "
                             f"is at {finger.fs_hz:g} Hz (resample through fydpad.channels)")
        if self._renderer is None:
            self._renderer = TextureRenderer(self.model, method=self.method, seed=self.seed,
                                             ramp_s=1e-6)
            v0 = float(finger.speed_mm_s[0]) if finger.speed_mm_s.size else 0.0
            self._renderer.warmup(v0, 0.5)
        return self._renderer.block(finger.speed_mm_s, finger.contact)

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float, ...]:
        return (self.source.tick(t_s, contact, x_mm, y_mm),)

    def reset(self) -> None:
        self._renderer = None
        if self._source is not None:
            # A new stimulus starts from no speed, not the last one's (its filter would
            # play for the low-pass's ~50 ms).
            self._source.renderer.reset()
            self._source.speed = type(self._source.speed)(cutoff_hz=self._source.speed.cutoff_hz)


def _check_channel(family: Any, channel: str) -> None:
    if channel not in family.channels:
        raise UserError(f"a {family.kind} model renders {', '.join(family.channels)}; "
                        f"not {channel!r}")


def _lpc_from_json(data: dict[str, Any], where: str) -> LpcFamily:
    from fydpad.texture.model_file import parse_model

    return LpcFamily(parse_model(data, where), where)


def _lpc_fit(scans: list, **options: Any) -> dict[str, Any]:
    from fydpad.texture.fit import fit_texture
    from fydpad.texture.model_file import model_to_json

    model, _ = fit_texture(scans, **options)
    return model_to_json(model)


register_kind(Kind("lpc", _lpc_from_json, _lpc_fit,
                   "speed-indexed LPC models, eq. 5 of paper 004 (vibration, 1 kHz)"))


def read_scans(paths: list[str]) -> list:
    """Texture scans (``fydpad.texture.scan_io.read_scan``) with their ``x_mm`` and
    ``friction_n`` columns attached when present (the position-indexed families need
    them; ``Scan`` itself keeps only what the LPC fit uses)."""
    from fydpad.texture.scan_io import read_scan
    from vision.recording import RecordingError, read_csv_columns

    out = []
    try:
        for p in paths:
            sc = read_scan(p)
            cols = read_csv_columns(p, ("t_s",), ("x_mm", "friction_n"),
                                    empty_ok=("x_mm", "friction_n"))
            for name in ("x_mm", "friction_n"):
                col = cols.get(name)
                setattr(sc, name, col if col is not None and np.isfinite(col).all() else None)
            out.append(sc)
    except RecordingError as exc:
        raise UserError(str(exc)) from None
    return out


def finger_from_scan(scan: Any, fs_hz: float | None = None) -> FingerBlock:
    """The finger stream of a scan (contact throughout; x from ``x_mm`` or the speed)."""
    x = getattr(scan, "x_mm", None)
    if x is None:
        x = np.cumsum(scan.speed_mm_s) / scan.fs_hz
    n = scan.t_s.size
    force = scan.force_n if getattr(scan, "force_n", None) is not None else np.ones(n)
    fb = FingerBlock(scan.fs_hz, np.asarray(scan.t_s, float), np.ones(n, bool),
                     np.asarray(x, float), np.zeros(n), np.asarray(scan.speed_mm_s, float),
                     np.asarray(force, float))
    return fb if fs_hz is None else resample_finger(fb, fs_hz)


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


__all__ = ["KINDS", "Kind", "LpcFamily", "TickPosition", "constant_stroke", "finger_from_scan",
           "fit_family", "load_family", "register_kind"]
