"""Errors the command line reports as one line, without a traceback: the tree of
:mod:`vision.errors`, re-exported here, and helpers that raise it."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

from vision.errors import DeviceFault, FydpadError, UserError

__all__ = ["DeviceFault", "FydpadError", "UserError", "one_line_warnings", "read_json"]


def read_json(path: str | Path, what: str = "JSON") -> Any:
    """The parsed JSON file at ``path``; a missing or unreadable file is a UserError that
    names it (``what`` says what the file should have been, e.g. "JSON model")."""
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path}: missing") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: not a readable {what} ({exc})") from None


def one_line_warnings(prefix: str) -> None:
    """Print this process's warnings as ``{prefix}: warning: message`` on one line (the
    default format adds the source file, line and code on a second line)."""

    def fmt(message, category, filename, lineno, line=None) -> str:
        text = " ".join(str(message).split())
        kind = "" if category is UserWarning else f" ({category.__name__})"
        return f"{prefix}: warning{kind}: {text}\n"

    warnings.formatwarning = fmt
