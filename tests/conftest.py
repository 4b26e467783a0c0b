"""Shared fixtures: small recordings made by the project's own writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vision.mapping import flip_frame, workspace_to_roi
from vision.recording import PadMeta, PadRecordingWriter

REPO = Path(__file__).resolve().parents[1]


def write_blob_recording(
    recdir: Path,
    positions_mm: list[tuple[float, float] | None],
    image_flip: str = "horizontal",
    fps: float = 30.0,
    with_ir: bool = True,
) -> PadMeta:
    """A recording of a dark square blob at known workspace positions (None: no contact).

    Frames are drawn as seen from above, then un-flipped into the raw camera image.
    """
    meta = PadMeta(roi_px=(24, 22, 592, 414), workspace_mm=(100.0, 70.0), fps=fps,
                   frame_size=(640, 480), image_flip=image_flip)
    with PadRecordingWriter(recdir, meta, jpeg_quality=95) as w:
        for k, pos in enumerate(positions_mm):
            top = np.full((480, 640, 3), 225, np.uint8)
            if pos is not None:
                u, v = workspace_to_roi(pos[0], pos[1], meta.roi_px, meta.workspace_mm)
                u0, v0 = round(float(u)), round(float(v))
                top[v0 - 12 : v0 + 12, u0 - 12 : u0 + 12] = 40
            w.write_frame(flip_frame(top, image_flip))
            contact = pos is not None
            w.write_truth(k / fps, k, contact, *(pos if contact else (0.0, 0.0)),
                          5.0 if contact else 0.0)
            if with_ir:
                w.write_ir(k / fps, 1.31, 1.31, 1.31)
                w.write_force(k / fps, 2.0 if contact else 0.0)
    return meta


@pytest.fixture
def blob_recording(tmp_path: Path) -> Path:
    rec = tmp_path / "rec"
    positions: list[tuple[float, float] | None] = [None, None]
    positions += [(-30.0 + 6 * i, 20.0 - 4 * i) for i in range(10)]
    positions += [None]
    write_blob_recording(rec, positions)
    return rec
