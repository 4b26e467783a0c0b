"""Small measuring tools for the synthetic pad's tests: grey flipped frames, patches."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from fydpad.synth import SyntheticPad
from vision.mapping import flip_frame, roi_to_workspace


def grey_from_above(pad: SyntheticPad, k: int) -> NDArray[np.float64]:
    """Frame k as seen from above (flip undone), in grey levels."""
    raw = pad.frame(k)
    return cv2.cvtColor(flip_frame(raw, pad.cfg.image_flip), cv2.COLOR_BGR2GRAY).astype(float)


def roi(pad: SyntheticPad, grey: NDArray[np.float64]) -> NDArray[np.float64]:
    x, y, w, h = pad.cfg.roi_px
    return grey[y:y + h, x:x + w]


def to_mm(pad: SyntheticPad, u_px: float, v_px: float) -> tuple[float, float]:
    x, y = roi_to_workspace(u_px, v_px, pad.cfg.roi_px, pad.cfg.workspace_mm)
    return float(x), float(y)


def patch(pad: SyntheticPad, grey: NDArray[np.float64]) -> tuple[NDArray[np.bool_], float]:
    """Pixels of the dark patch: darker than halfway between the darkest (smoothed) level
    and the frame's median, connected to the darkest point; and that darkest level."""
    smooth = cv2.GaussianBlur(grey, (0, 0), 3)
    lo = float(smooth.min())
    mask = (smooth < 0.5 * (lo + float(np.median(grey)))).astype(np.uint8)
    _, labels = cv2.connectedComponents(mask)
    v, u = np.unravel_index(int(np.argmin(smooth)), smooth.shape)
    return labels == labels[v, u], lo


def darkness_centroid_mm(pad: SyntheticPad, grey: NDArray[np.float64]) -> tuple[float, float]:
    """Centroid of the light the patch blocks (median - grey), weighted, in workspace mm."""
    mask, _ = patch(pad, grey)
    vv, uu = np.nonzero(mask)
    wgt = np.median(grey) - grey[vv, uu]
    return to_mm(pad, float(np.sum((uu + 0.5) * wgt) / wgt.sum()),
                 float(np.sum((vv + 0.5) * wgt) / wgt.sum()))


def steady_contact_frames(pad: SyntheticPad) -> list[int]:
    """Frames in contact whose neighbours are in contact too."""
    c = [pad.truth(k).contact for k in range(pad.frame_count)]
    return [k for k in range(1, len(c) - 1) if c[k - 1] and c[k] and c[k + 1]]


def processed(pad: SyntheticPad, k: int) -> NDArray[np.float64]:
    """The ROI at the paper's 160 x 120 processing size (area average), as its tracker
    sees it before the threshold."""
    g = roi(pad, grey_from_above(pad, k))
    return cv2.resize(g, (160, 120), interpolation=cv2.INTER_AREA)
