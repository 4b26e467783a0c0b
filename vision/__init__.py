"""Finger sensing for the FYD-pad: contact centroid, indentation and force.

This package imports nothing from the rest of the project (docs/architecture.md).
"""

from __future__ import annotations

from typing import Any

__all__ = ["Contact", "ContactTracker", "FingerState"]


def __getattr__(name: str) -> Any:
    # Loaded when first asked for, not on ``import vision``: vision.contact loads OpenCV,
    # which every ``import vision.errors`` (the commands' start) would otherwise pay for.
    if name in ("Contact", "ContactTracker"):
        from vision import contact  # lazy: OpenCV, see above

        return getattr(contact, name)
    if name == "FingerState":
        from vision.state import FingerState  # lazy, as the names above

        return FingerState
    raise AttributeError(f"module 'vision' has no attribute {name!r}")
