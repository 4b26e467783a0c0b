"""The texture-family registry: read, fit and select models of every family.

A model file is JSON with ``"format": "fydpad-texture-model"`` and ``"kind"`` naming its
family (none: ``lpc``); a HaTT model is its XML file. A spec is ``[KIND:]MODEL.json`` or
``[penn:]FILE.xml``. Each family's module offers one ``Kind``; nothing imports this back.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fydpad.errors import UserError
from fydpad.texture.families import friction, grating
from fydpad.texture.families.mlp import render as mlp
from fydpad.texture.families.penn import render as penn
from fydpad.texture.family import Kind, TextureFamily, read_model_json
from fydpad.texture.lpc import family as lpc

KINDS: dict[str, Kind] = {k.name: k for k in (lpc.KIND, friction.KIND, grating.KIND,
                                              mlp.KIND, penn.KIND)}
#: The kinds the commands offer.
KIND_NAMES = tuple(KINDS)
#: The kinds ``fydpad texture fit`` and ``compare`` fit from scans (not HaTT's).
FIT_KIND_NAMES = tuple(k.name for k in KINDS.values() if k.fit is not None)


def get_kind(name: str) -> Kind:
    if name not in KINDS:
        raise UserError(f"unknown texture kind {name!r} (known: {', '.join(sorted(KINDS))})")
    return KINDS[name]


def split_spec(spec: str) -> tuple[str | None, str]:
    """``KIND:PATH`` -> (KIND, PATH); a bare path -> (None, PATH)."""
    head, sep, tail = spec.partition(":")
    if sep and head in KINDS:
        return head, tail
    return None, spec


def model_kind(data: dict[str, Any]) -> str:
    """The family of a parsed model file (no ``kind``: an LPC model)."""
    return str(data.get("kind", "lpc"))


def _file_format_kind(want: str | None, path: str) -> str | None:
    """The kind of a spec whose file is not JSON: ``penn:`` or a bare ``.xml`` path."""
    want = "penn" if want is None and path.lower().endswith(".xml") else want
    return want if want is not None and get_kind(want).from_file is not None else None


def load_family(spec: str | Path) -> TextureFamily:
    """A ready-to-render family from ``[KIND:]MODEL.json`` or ``[penn:]FILE.xml``."""
    want, path = split_spec(str(spec))
    own = _file_format_kind(want, path)
    if own is not None:
        return KINDS[own].from_file(path)  # type: ignore[misc]
    data = read_model_json(path)
    kind = model_kind(data)
    if want is not None and want != kind:
        raise UserError(f"{path}: key 'kind' is {kind!r}, but the spec asked for {want!r}")
    if kind not in KINDS:
        raise UserError(f"{path}: key 'kind' is {kind!r}, not a texture family (known: "
                        f"{', '.join(sorted(KINDS))})")
    return KINDS[kind].from_json(data, str(path))


def spec_kind(spec: str | Path) -> str:
    """The family of ``[KIND:]MODEL`` without building it (JSON ``kind``, or penn)."""
    want, path = split_spec(str(spec))
    own = _file_format_kind(want, path)
    return own if own is not None else model_kind(read_model_json(path))


def fitted_kind(name: str) -> Kind:
    """:func:`get_kind` for a family fitted from scans (not HaTT's)."""
    k = get_kind(name)
    if k.fit is None:
        raise UserError(f"texture kind {name!r} is not fitted from scans")
    return k


def fit_family(kind: str, scans: list, **options: Any) -> dict[str, Any]:
    """Fit a model of ``kind`` from scans; returns the model file's JSON (with ``kind``)."""
    return fitted_kind(kind).fit(scans, **options)  # type: ignore[misc]
