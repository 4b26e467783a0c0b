"""The experiment's stimuli: the paper's four with grating texture models, or a file.

By default each stimulus renders a rectangular grating model (Ito 2019 4.2, the
FYD-pad's specimens: 90 % ridge, the default 8:2 vibrotactile/friction ratio) of its
period, written to ``<cache>/textures/grating-<period>mm.json`` (``fydpad run``: the
user's cache, ~/.cache/fydpad) so the plan and the
render process name a real file (rewritten, atomically, whenever its content would
differ: a file of an older fit or a torn write is never used). ``--web-stimuli
FILE.json`` replaces them: a JSON list of ``{"name", "stiffness_n_per_mm",
"grating_mm", "texture", "description"}`` (docs/experiment.md).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import replace
from pathlib import Path

from fydpad.errors import UserError, read_json
from fydpad.web.experiment import PAPER_STIMULI, Stimulus
from vision.strict_json import finite


def grating_textures(stimuli: tuple[Stimulus, ...] | list[Stimulus], texture_dir: Path
                     ) -> list[Stimulus]:
    """``stimuli`` with ``texture`` set to a grating model of each ``grating_mm``."""
    # lazy: the texture library (SciPy) loads only for stimuli that are gratings
    from fydpad.texture.families.grating import fit_grating

    texture_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for s in stimuli:
        path = texture_dir / f"grating-{s.grating_mm:g}mm.json"
        model = fit_grating(wavelength_mm=s.grating_mm, profile="rect", ridge_fraction=0.9)
        # As fydpad.texture.families.save_model_json writes it.
        _write_if_changed(path, json.dumps(finite(model), indent=1, allow_nan=False) + "\n")
        out.append(replace(s, texture=f"grating:{path}"))
    return out


def _write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` unless the file already holds it, atomically (a temporary file in
    the same folder, then ``os.replace``): a reader sees the old file or the new one,
    never a part of it; two stations starting at once both end with a whole file."""
    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except (OSError, UnicodeDecodeError):
        pass  # missing or unreadable: (re)write it
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_stimuli(path: str | Path) -> list[Stimulus]:
    """Stimuli from a JSON file; an error names the file, the entry and the key."""
    path = Path(path)
    data = read_json(path, "JSON")
    if not isinstance(data, list) or len(data) < 2:
        raise UserError(f"{path}: expected a JSON list of at least two stimuli")
    out = []
    for i, d in enumerate(data):
        where = f"{path}: stimulus {i + 1}"
        if not isinstance(d, dict):
            raise UserError(f"{where}: expected an object")
        unknown = set(d) - {"name", "stiffness_n_per_mm", "grating_mm", "texture",
                            "description"}
        if unknown:
            raise UserError(f"{where}: unknown key '{sorted(unknown)[0]}'")
        name = d.get("name")
        if not isinstance(name, str) or not name:
            raise UserError(f"{where}: key 'name' must be a non-empty string")
        for key in ("stiffness_n_per_mm", "grating_mm"):
            v = d.get(key, 0.0 if key == "grating_mm" else None)  # 0: not a grating
            if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(
                    v) or not (v > 0 or (key == "grating_mm" and v == 0)):
                raise UserError(f"{where}: key '{key}' must be a positive number")
        texture = d.get("texture")
        if texture is not None:
            if not isinstance(texture, str):
                raise UserError(f"{where}: key 'texture' must be a model path")
            # lazy: the texture library (SciPy) loads only for stimuli naming a model
            from fydpad.texture.families import load_family, split_spec

            kind, model = split_spec(texture)
            if not Path(model).is_absolute():  # relative to the stimuli file
                model = str(path.parent / model)
                texture = f"{kind}:{model}" if kind else model
            load_family(texture)  # a bad model fails here, naming its file
        out.append(Stimulus(name, float(d["stiffness_n_per_mm"]),
                            float(d.get("grating_mm", 0.0)),
                            str(d.get("description", "")), texture))
    if len({s.name for s in out}) != len(out):
        raise UserError(f"{path}: stimulus names must be distinct")
    return out


def experiment_stimuli(stimuli_file: str | Path | None, model_dir: str | Path
                       ) -> list[Stimulus]:
    """The stimuli of ``--web-stimuli``, else the paper's four with grating models
    written under ``model_dir``/textures."""
    if stimuli_file is not None:
        return load_stimuli(stimuli_file)
    return grating_textures(PAPER_STIMULI, Path(model_dir) / "textures")
