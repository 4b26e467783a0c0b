"""Opening what a command works on: a recording or a live camera, as one frame source."""

from __future__ import annotations

from dataclasses import dataclass, replace

from fydpad.config import StationConfig
from fydpad.errors import UserError
from vision.recording import PadMeta, PadRecording
from vision.sources import CameraConfig, CameraSource, FrameSource, SourceError, VideoSource


@dataclass
class OpenedSource:
    """A frame source with the geometry that applies to its frames."""

    source: FrameSource
    meta: PadMeta
    #: The recording, when the source is one (its sensor and truth files).
    recording: PadRecording | None
    #: The camera's configuration, when the source is a live camera.
    camera: CameraConfig | None

    @property
    def total_frames(self) -> int | None:
        return self.recording.frame_count or None if self.recording is not None else None


def open_source(config: StationConfig, recdir: str | None, camera: str | None) -> OpenedSource:
    """A recording directory or a live camera (exactly one of them)."""
    if (recdir is None) == (camera is None):
        raise UserError("give either a recording directory RECDIR or --camera N")
    if recdir is not None:
        rec = PadRecording(recdir)
        return OpenedSource(VideoSource(rec), rec.meta, rec, None)
    cam = replace(config.camera, device=str(camera))
    try:
        source = CameraSource(cam)
    except SourceError as exc:
        raise UserError(str(exc)) from None
    meta = PadMeta(roi_px=cam.roi_px, workspace_mm=cam.workspace_mm, fps=source.fps,
                   frame_size=source.frame_size, image_flip=cam.image_flip)
    return OpenedSource(source, meta, None, cam)
