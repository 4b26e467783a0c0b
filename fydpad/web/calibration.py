"""The workspace calibration from the web page (9 presses on a 3 x 3 grid), as pure
state over the live tracker's output.

The page shows the marked points (``vision.calibration.default_targets_mm``: a square
grid over 80 % of the workspace, far row first, left to right) and asks for one press
at a time. The collector is fed every new frame's contact centroid (flipped-frame
pixels) at its frame time and waits first for the fabric to be clear for ``clear_s``
(a finger already down when the flow starts is not point 1), then takes each press held
at least ``min_hold_s`` and lifted as the next point: its centroid is
``vision.calibration.press_centroids`` of its frames (the median of the middle three
fifths), exactly as ``fydpad calibrate workspace`` takes it from a recording. After the
last point the homography is fitted with ``homography_from_presses``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vision.calibration import (
    CalibrationError,
    CameraIntrinsics,
    WorkspaceHomography,
    default_targets_mm,
    homography_from_presses,
    press_centroids,
)


@dataclass
class PressCollector:
    """Collects one press per marked point, in order (``feed`` per frame)."""

    targets_mm: np.ndarray
    min_hold_s: float = 0.4
    clear_s: float = 1.0
    presses_px: list[tuple[float, float]] = field(default_factory=list)
    #: "clear": waiting for the fabric to be clear; "press": waiting for point k; "done".
    state: str = "clear"
    #: Presses too short to count (the page tells the user to hold still longer).
    short_presses: int = 0
    _clear_since_s: float = math.nan
    _run: list[tuple[float, float, float]] = field(default_factory=list)
    _last_t_s: float = -math.inf

    @classmethod
    def for_workspace(cls, workspace_mm: tuple[float, float], points: int = 9,
                      min_hold_s: float = 0.4, clear_s: float = 1.0) -> PressCollector:
        return cls(default_targets_mm(workspace_mm, points), min_hold_s, clear_s)

    @property
    def next_index(self) -> int:
        """The 0-based index of the point to press next (== len(targets) when done)."""
        return len(self.presses_px)

    def feed(self, t_s: float, contact: bool, u_px: float, v_px: float) -> None:
        """One frame of the tracker: the contact and its centroid (flipped-frame pixels)."""
        if self.state == "done" or not t_s > self._last_t_s:
            return  # a frame seen twice, or out of order: ignored
        self._last_t_s = t_s
        touching = bool(contact) and math.isfinite(u_px) and math.isfinite(v_px)
        if self.state == "clear":
            if touching:
                self._clear_since_s = math.nan
            elif math.isnan(self._clear_since_s):
                self._clear_since_s = t_s
            elif t_s - self._clear_since_s >= self.clear_s:
                self.state = "press"
            return
        if touching:
            self._run.append((t_s, u_px, v_px))
            return
        if self._run:  # the finger lifted: was that a press held long enough?
            run = np.asarray(self._run)
            self._run = []
            found = press_centroids(run[:, 0], np.ones(len(run), bool), run[:, 1], run[:, 2],
                                    self.min_hold_s)
            if not found:
                self.short_presses += 1
                return
            self.presses_px.append(found[0])
            if len(self.presses_px) == len(self.targets_mm):
                self.state = "done"

    def fit(self, image_flip: str, frame_size: tuple[int, int],
            intrinsics: CameraIntrinsics | None) -> tuple[WorkspaceHomography, np.ndarray]:
        """The homography and each point's residual (mm); CalibrationError before done."""
        if self.state != "done":
            raise CalibrationError(f"{self.next_index} of {len(self.targets_mm)} points "
                                   "pressed so far")
        return homography_from_presses(self.presses_px, self.targets_mm, image_flip,
                                       frame_size, intrinsics)

    def status(self) -> dict:
        return {"state": self.state, "next": self.next_index,
                "targets_mm": np.round(self.targets_mm, 3).tolist(),
                "presses_px": [[round(u, 2), round(v, 2)] for u, v in self.presses_px],
                "pressing": bool(self._run), "short_presses": self.short_presses,
                "min_hold_s": self.min_hold_s, "clear_s": self.clear_s}
