"""Contact centroid of the finger from the under-fabric camera (paper section II-B.1).

``ContactTracker`` takes one raw camera frame and returns the contact in the
workspace frame, or None. ``method="paper"`` is the paper's algorithm exactly:

1. flip the raw frame so that it shows the fabric as seen from above;
2. crop the ROI and resize it to the processing size (160 x 120 by default);
3. convert to grey levels;
4. pixels darker than the threshold (150) are the finger;
5. weights ``k = exp(-(I - Imin)^2 / (2 sigma^2))`` with ``sigma = (Imax - Imin) / beta``
   (beta = 5) over the finger pixels; when ``sigma = 0`` every finger pixel weighs 1;
6. the weighted mean of the pixel centres, mapped to the workspace (docs/recording_format.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.calibration import CalibratedMapping
from vision.mapping import flip_frame, roi_to_workspace
from vision.robust import RobustParams, RobustTracker

PAPER_THRESHOLD = 150
PAPER_BETA = 5.0
PAPER_PROCESSING_SIZE = (160, 120)
DEFAULT_ROI_PX = (24, 22, 592, 414)
DEFAULT_WORKSPACE_MM = (100.0, 70.0)
METHODS = ("robust", "paper")


@dataclass
class TrackerConfig:
    """The contact tracker's settings; defaults are the paper's (section II-B.1)."""

    method: str = "robust"
    threshold: int = PAPER_THRESHOLD
    beta: float = PAPER_BETA
    processing_size: tuple[int, int] = PAPER_PROCESSING_SIZE
    robust: RobustParams = field(default_factory=RobustParams)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if not 0 < self.threshold <= 256:
            raise ValueError(f"threshold must be in 1..256, got {self.threshold}")
        if self.beta <= 0:
            raise ValueError(f"beta must be positive, got {self.beta}")
        if len(self.processing_size) != 2 or min(self.processing_size) <= 0:
            raise ValueError(f"processing_size must be positive, got {self.processing_size}")


@dataclass(frozen=True, slots=True)
class Contact:
    """A detected contact: centroid in the workspace and in the flipped full frame."""

    x_mm: float
    y_mm: float
    #: Centroid in pixels of the flipped full frame (continuous coordinates).
    u_px: float
    v_px: float
    area_mm2: float


class ContactTracker:
    """Finds the finger's contact centroid in camera frames.

    Every argument defaults to the paper's value, so
    ``ContactTracker(roi_px=meta["roi_px"], workspace_mm=meta["workspace_mm"])`` works.
    """

    def __init__(
        self,
        roi_px: tuple[int, int, int, int] = DEFAULT_ROI_PX,
        workspace_mm: tuple[float, float] = DEFAULT_WORKSPACE_MM,
        image_flip: str = "none",
        method: str = "robust",
        threshold: int = PAPER_THRESHOLD,
        beta: float = PAPER_BETA,
        processing_size: tuple[int, int] = PAPER_PROCESSING_SIZE,
        robust: RobustParams | None = None,
        calibration: CalibratedMapping | None = None,
    ):
        # One place checks the tracker's settings: its configuration dataclass.
        TrackerConfig(method, threshold, beta, processing_size)
        x, y, w, h = (int(v) for v in roi_px)
        if w <= 0 or h <= 0 or x < 0 or y < 0:
            raise ValueError(f"roi_px must be [x, y, w, h] with w, h > 0, got {list(roi_px)}")
        pw, ph = (int(v) for v in processing_size)
        self.roi_px = (x, y, w, h)
        self.workspace_mm = (float(workspace_mm[0]), float(workspace_mm[1]))
        self.image_flip = image_flip
        flip_frame(np.zeros((1, 1), np.uint8), image_flip)  # validates the name
        self.method = method
        self.threshold = int(threshold)
        self.beta = float(beta)
        self.processing_size = (pw, ph)
        # Pixel centres of the processing grid, in ROI pixels of the full frame.
        self._u_centres = x + (np.arange(pw) + 0.5) * (w / pw)
        self._v_centres = y + (np.arange(ph) + 0.5) * (h / ph)
        self._cell_area_mm2 = (self.workspace_mm[0] / pw) * (self.workspace_mm[1] / ph)
        self._levels = np.arange(256, dtype=np.float64)
        #: When set, contact points go through lens undistortion and the workspace
        #: homography instead of the linear ROI mapping.
        self.calibration = calibration
        self._robust = (
            RobustTracker(self.roi_px, image_flip, self.workspace_mm, robust)
            if method == "robust" else None
        )

    def with_settings(self, **changes) -> ContactTracker:
        """A new tracker like this one with some arguments changed (roi_px, threshold,
        image_flip, ...); a live station swaps it in between two frames."""
        args = {
            "roi_px": self.roi_px, "workspace_mm": self.workspace_mm,
            "image_flip": self.image_flip, "method": self.method, "threshold": self.threshold,
            "beta": self.beta, "processing_size": self.processing_size,
            "robust": self._robust.params if self._robust is not None else None,
            "calibration": self.calibration,
        }
        unknown = set(changes) - set(args)
        if unknown:
            raise TypeError(f"unknown tracker setting(s): {', '.join(sorted(unknown))}")
        return ContactTracker(**{**args, **changes})

    def reset(self) -> None:
        """Forget what was learned from earlier frames (the robust method's background)."""
        if self._robust is not None:
            self._robust.reset()

    def __repr__(self) -> str:
        return (
            f"ContactTracker(method={self.method!r}, roi_px={list(self.roi_px)}, "
            f"workspace_mm={list(self.workspace_mm)}, image_flip={self.image_flip!r}, "
            f"threshold={self.threshold}, beta={self.beta}, "
            f"processing_size={list(self.processing_size)})"
        )

    def preprocess(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """Steps 1-3: flip, ROI, resize to the processing size, grey levels."""
        if frame.ndim not in (2, 3) or frame.dtype != np.uint8:
            raise ValueError(f"expected an 8-bit grey or BGR frame, got {frame.dtype}{frame.shape}")
        x, y, w, h = self.roi_px
        fh, fw = frame.shape[:2]
        if x + w > fw or y + h > fh:
            raise ValueError(f"ROI {list(self.roi_px)} lies outside the {fw}x{fh} frame")
        roi = flip_frame(frame, self.image_flip)[y : y + h, x : x + w]
        if (w, h) != self.processing_size:
            roi = cv2.resize(roi, self.processing_size, interpolation=cv2.INTER_AREA)
        if roi.ndim == 3:
            roi = cv2.cvtColor(roi, cv2.COLOR_BGR2GRAY)
        return roi

    def process(self, frame: NDArray[np.uint8]) -> Contact | None:
        """The contact in one raw camera frame (BGR or grey), or None without contact."""
        if self._robust is None:
            contact = self.centroid(self.preprocess(frame))
        else:
            if frame.ndim not in (2, 3) or frame.dtype != np.uint8:
                raise ValueError(
                    f"expected an 8-bit grey or BGR frame, got {frame.dtype}{frame.shape}"
                )
            r = self._robust.process(frame)
            if r is None:
                return None
            x_mm, y_mm = roi_to_workspace(r.u_px, r.v_px, self.roi_px, self.workspace_mm)
            contact = Contact(float(x_mm), float(y_mm), r.u_px, r.v_px, r.area_mm2)
        if contact is not None and self.calibration is not None:
            x_mm, y_mm = self.calibration.to_workspace(
                contact.u_px, contact.v_px, (frame.shape[1], frame.shape[0])
            )
            contact = Contact(x_mm, y_mm, contact.u_px, contact.v_px, contact.area_mm2)
        return contact

    def centroid(self, grey: NDArray[np.uint8]) -> Contact | None:
        """Steps 4-6 on a processing-size grey image."""
        mask = grey < self.threshold
        n = int(np.count_nonzero(mask))
        if n == 0:
            return None
        values = grey[mask]
        i_min = float(values.min())
        i_max = float(values.max())
        sigma = (i_max - i_min) / self.beta
        if sigma > 0:
            # One weight per grey level, looked up per pixel: 256 exps instead of n.
            lut = np.exp(-((self._levels - i_min) ** 2) / (2.0 * sigma * sigma))
        else:
            lut = np.ones(256)
        weights = np.where(mask, lut[grey], 0.0)
        total = weights.sum()
        u_px = float(weights.sum(axis=0) @ self._u_centres / total)
        v_px = float(weights.sum(axis=1) @ self._v_centres / total)
        x_mm, y_mm = roi_to_workspace(u_px, v_px, self.roi_px, self.workspace_mm)
        return Contact(
            x_mm=float(x_mm), y_mm=float(y_mm), u_px=u_px, v_px=v_px,
            area_mm2=n * self._cell_area_mm2,
        )
