"""Finger sensing for the FYD-pad: contact centroid, indentation and force.

This package imports nothing from the rest of the project (docs/architecture.md).
"""

from vision.contact import Contact, ContactTracker
from vision.state import FingerState

__all__ = ["Contact", "ContactTracker", "FingerState"]
