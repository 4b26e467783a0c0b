"""Where the bundled sample recordings are."""

from __future__ import annotations

import os
from pathlib import Path

from fydpad.errors import UserError


def recordings_dir() -> Path:
    """The ``recordings/`` directory of the source tree, or ``$FYDPAD_RECORDINGS``."""
    env = os.environ.get("FYDPAD_RECORDINGS")
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[1] / "recordings")
    for path in candidates:
        if path.is_dir():
            return path
    raise UserError(
        "the bundled recordings are not found: install from a clone of the repository "
        "(pip install -e .) or set FYDPAD_RECORDINGS to the recordings directory"
    )


def bundled_recording(name: str) -> Path:
    path = recordings_dir() / name
    if not (path / "meta.json").exists():
        raise UserError(f"{path}: no bundled recording named {name!r}")
    return path
