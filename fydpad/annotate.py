"""Drawing the tracker's decision on camera frames (like the paper's Fig. 4)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.contact import Contact
from vision.mapping import flip_frame


def annotate_frame(
    raw_frame: NDArray[np.uint8],
    image_flip: str,
    roi_px: tuple[int, int, int, int],
    contact: Contact | None,
    truth_uv_px: tuple[float, float] | None = None,
    label: str = "",
) -> NDArray[np.uint8]:
    """The flipped frame (fabric seen from above) with the ROI, the contact and the truth."""
    img = flip_frame(raw_frame, image_flip)
    img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img.copy()
    x, y, w, h = roi_px
    cv2.rectangle(img, (x, y), (x + w - 1, y + h - 1), (255, 200, 0), 1)
    if truth_uv_px is not None:
        cv2.circle(img, (round(truth_uv_px[0]), round(truth_uv_px[1])), 6, (0, 200, 0), 1,
                   cv2.LINE_AA)
    if contact is not None:
        u, v = round(contact.u_px), round(contact.v_px)
        cv2.drawMarker(img, (u, v), (0, 0, 255), cv2.MARKER_CROSS, 18, 2, cv2.LINE_AA)
        text = f"x {contact.x_mm:+6.1f} mm  y {contact.y_mm:+6.1f} mm"
    else:
        text = "no contact"
    cv2.putText(img, f"{label} {text}".strip(), (8, img.shape[0] - 10),
                cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 255), 1, cv2.LINE_AA)
    return img


class AnnotatedVideoWriter:
    """An MP4 (mp4v) of annotated frames."""

    def __init__(self, path: str | Path, fps: float, frame_size: tuple[int, int]):
        self.path = Path(path)
        fourcc = cv2.VideoWriter_fourcc(*("MJPG" if self.path.suffix == ".avi" else "mp4v"))
        self._writer = cv2.VideoWriter(str(self.path), fourcc, fps, frame_size)
        if not self._writer.isOpened():
            raise OSError(f"{self.path}: OpenCV cannot write this video")

    def write(self, frame: NDArray[np.uint8]) -> None:
        self._writer.write(frame)

    def close(self) -> None:
        self._writer.release()
