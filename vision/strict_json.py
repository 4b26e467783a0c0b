"""Strict JSON (RFC 8259) for every file and message the project writes: a value that is
not a finite number (NaN, inf: missing or undefined) is written as null, never as the
``NaN`` that Python's json module writes by default and every strict parser rejects."""

from __future__ import annotations

import math
import sys
from typing import Any


def finite(obj: Any) -> Any:
    """``obj`` with every non-finite float (Python or NumPy) replaced by None, NumPy
    scalars and arrays as Python numbers and lists, tuples as lists."""
    if isinstance(obj, dict):
        return {k: finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [finite(v) for v in obj]
    # No NumPy object exists unless NumPy is loaded: `--help` paths need not import it.
    np = sys.modules.get("numpy")
    if np is not None:
        if isinstance(obj, np.ndarray):
            return finite(obj.tolist())
        if isinstance(obj, np.generic):
            obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
