"""Image to workspace geometry: the camera flip and the ROI mapping (docs/recording_format.md).

Pixel coordinates are continuous: pixel (col i, row j) covers [i, i+1) x [j, j+1), so
its centre is (i + 0.5, j + 0.5). The workspace frame is the fabric seen from above,
origin at its centre, x to the user's right, y away from the user.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

_FLIP_CODES = {"none": None, "horizontal": 1, "vertical": 0, "both": -1}


def flip_frame(frame: NDArray[np.uint8], image_flip: str) -> NDArray[np.uint8]:
    """Flip a raw camera frame so that it shows the fabric as seen from above."""
    try:
        code = _FLIP_CODES[image_flip]
    except KeyError:
        raise ValueError(
            f"image_flip must be one of {tuple(_FLIP_CODES)}, got {image_flip!r}"
        ) from None
    return frame if code is None else cv2.flip(frame, code)


def flip_point(
    u_px: float, v_px: float, image_flip: str, frame_size: tuple[int, int]
) -> tuple[float, float]:
    """Map a continuous point between the raw and the flipped frame (the map is its own inverse)."""
    w, h = frame_size
    if image_flip in ("horizontal", "both"):
        u_px = w - u_px
    if image_flip in ("vertical", "both"):
        v_px = h - v_px
    return u_px, v_px


def roi_to_workspace(
    u_px: ArrayLike,
    v_px: ArrayLike,
    roi_px: tuple[int, int, int, int],
    workspace_mm: tuple[float, float],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """docs/recording_format.md's linear map from flipped-frame pixels to the workspace:
    ``x_mm = ((u - x)/w - 0.5) * W_mm``, ``y_mm = (0.5 - (v - y)/h) * H_mm``."""
    x, y, w, h = roi_px
    u = np.asarray(u_px, dtype=np.float64)
    v = np.asarray(v_px, dtype=np.float64)
    return ((u - x) / w - 0.5) * workspace_mm[0], (0.5 - (v - y) / h) * workspace_mm[1]


def workspace_to_roi(
    x_mm: ArrayLike,
    y_mm: ArrayLike,
    roi_px: tuple[int, int, int, int],
    workspace_mm: tuple[float, float],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Inverse of :func:`roi_to_workspace`: workspace mm to flipped-frame pixels."""
    x, y, w, h = roi_px
    xm = np.asarray(x_mm, dtype=np.float64)
    ym = np.asarray(y_mm, dtype=np.float64)
    return x + (xm / workspace_mm[0] + 0.5) * w, y + (0.5 - ym / workspace_mm[1]) * h
