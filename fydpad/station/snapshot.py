"""What the station shows to onlookers (the web view, the terminal status): the latest
frame, contact and finger state, swapped in as one reference by the vision loop.

Readers take ``Snapshot.latest()`` whenever they like; the vision loop never waits for
them and never copies a frame for them (the frame array is handed over, not copied:
the source allocates a new one per frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vision.contact import Contact
from vision.state import FingerState


@dataclass(frozen=True)
class View:
    """One frame's worth of what the station knows."""

    frame_index: int
    raw_frame: NDArray[np.uint8]
    contact: Contact | None
    state: FingerState


class Snapshot:
    """A one-slot, latest-only hand-off (a reference swap: atomic under the GIL)."""

    def __init__(self) -> None:
        self._view: View | None = None

    def publish(self, view: View) -> None:
        self._view = view

    def latest(self) -> View | None:
        return self._view
