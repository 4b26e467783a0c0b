"""Frame sources: a live camera, a recorded video, or the simulated pad, behind one Protocol."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.calibration import CameraIntrinsics, WorkspaceHomography
from vision.errors import DeviceFault
from vision.recording import PadRecording


class SourceError(DeviceFault, RuntimeError):
    """A frame source is missing, gives no frames, or failed; the message names the device."""

    device = "camera"
    check = "the camera index or path (`ls /dev/video*` lists video devices)"


@dataclass(frozen=True, slots=True)
class Frame:
    """One raw camera frame (not flipped) and its capture time."""

    index: int
    t_s: float
    image: NDArray[np.uint8]


@runtime_checkable
class FrameSource(Protocol):
    """Anything that yields raw camera frames in order."""

    #: Nominal frame rate in frames per second.
    fps: float
    #: Raw frame size (width, height) in pixels.
    frame_size: tuple[int, int]

    def frames(self) -> Iterator[Frame]: ...

    def close(self) -> None: ...


@dataclass
class CameraConfig:
    """The under-fabric webcam (paper II-A: Microsoft LifeCam HD-3000, 640x480 at 30 fps).

    ``image_flip`` says how to flip a raw frame to show the fabric seen from above;
    the camera looks up at the fabric, so its image is usually mirrored.
    """

    device: str = "0"
    frame_size: tuple[int, int] = (640, 480)
    fps: float = 30.0
    image_flip: str = "horizontal"
    roi_px: tuple[int, int, int, int] = (24, 22, 592, 414)
    workspace_mm: tuple[float, float] = (100.0, 70.0)
    #: The paper raises contrast and brightness to their maximum; set where the camera allows.
    maximise_contrast_brightness: bool = True
    #: Seconds to wait for the first frame before calling the camera silent.
    first_frame_timeout_s: float = 5.0
    #: Seconds without a frame, once frames came, before the camera is given up (a live
    #: camera drops single frames: those are counted, not fatal).
    outage_timeout_s: float = 2.0
    #: Lens model from ``fydpad calibrate camera`` (absent: no undistortion).
    intrinsics: CameraIntrinsics | None = None
    #: Image-to-workspace homography from ``fydpad calibrate workspace`` (absent: the
    #: linear ROI mapping of docs/recording_format.md).
    workspace_homography: WorkspaceHomography | None = None

    def __post_init__(self) -> None:
        if self.image_flip not in ("none", "horizontal", "vertical", "both"):
            raise ValueError(
                "image_flip must be one of 'none', 'horizontal', 'vertical', 'both'; "
                f"got {self.image_flip!r}"
            )


class VideoSource:
    """Frames of a pad session recording, decoded one at a time by OpenCV."""

    def __init__(self, recording: PadRecording):
        self.recording = recording
        self.fps = recording.fps
        self.frame_size = recording.video_size

    def frames(self) -> Iterator[Frame]:
        for k, t_s, image in self.recording.frames():
            yield Frame(k, t_s, image)

    def close(self) -> None:
        pass

    def __str__(self) -> str:
        return f"video {self.recording.video_path}"


#: Outages a live camera lists one by one (``CameraSource.dropouts``); more are counted.
MAX_DROPOUTS = 10_000


class CameraSource:
    """A live camera through OpenCV (device index or path).

    Capture times come from the host's monotonic clock, relative to the first frame.
    """

    def __init__(self, config: CameraConfig):
        self.config = config
        device: int | str = int(config.device) if config.device.isdigit() else config.device
        self._cap = cv2.VideoCapture(device)
        if not self._cap.isOpened():
            raise SourceError(
                f"camera {config.device!r}: cannot be opened (is it plugged in, and is the "
                "index or path right? `ls /dev/video*` lists video devices)"
            )
        w, h = config.frame_size
        self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, w)
        self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, h)
        self._cap.set(cv2.CAP_PROP_FPS, config.fps)
        if config.maximise_contrast_brightness:
            # Not every camera exposes these; the paper sets both to their maximum.
            self._cap.set(cv2.CAP_PROP_CONTRAST, 1.0)
            self._cap.set(cv2.CAP_PROP_BRIGHTNESS, 1.0)
        self.fps = float(self._cap.get(cv2.CAP_PROP_FPS) or config.fps)
        self.frame_size = (
            int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)) or w,
            int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) or h,
        )
        #: Reads that failed after the first frame (frames the camera dropped).
        self.read_failures = 0
        #: One per outage: [t_s of the last good frame (frames.csv's clock), its index,
        #: failed reads, seconds without a frame]; beyond MAX_DROPOUTS only counted.
        self.dropouts: list[list] = []
        self.dropouts_unlisted = 0

    def frames(self) -> Iterator[Frame]:
        """Frames until the camera fails for ``outage_timeout_s`` in a row; a failed read
        in between is a dropped frame, counted in ``read_failures`` and ``dropouts``."""
        t0: float | None = None
        k = 0
        deadline = time.monotonic() + self.config.first_frame_timeout_s
        failing_since: float | None = None
        last_t_s, outage = 0.0, [0.0, 0, 0, 0.0]
        retry_s = 0.25 / max(self.fps, 1.0)  # a failed read returns at once: no busy loop
        while True:
            ok, image = self._cap.read()
            now = time.monotonic()
            if not ok or image is None:
                if t0 is None:
                    if now < deadline:
                        time.sleep(0.01)
                        continue
                    raise SourceError(f"camera {self.config.device!r}: gave no frames in "
                                      f"{self.config.first_frame_timeout_s:g} s")
                self.read_failures += 1
                if failing_since is None:
                    failing_since, outage = now, [last_t_s, k - 1, 0, 0.0]
                    if len(self.dropouts) < MAX_DROPOUTS:
                        self.dropouts.append(outage)
                    else:
                        self.dropouts_unlisted += 1
                outage[2] += 1
                outage[3] = now - failing_since
                if now - failing_since >= self.config.outage_timeout_s:
                    raise SourceError(
                        f"camera {self.config.device!r}: no frame for "
                        f"{now - failing_since:.1f} s after frame {k - 1} ({k} frames, "
                        f"{self.read_failures} failed reads in all); is it still plugged in?")
                time.sleep(retry_s)
                continue
            failing_since = None
            if t0 is None:
                t0 = now
            last_t_s = now - t0
            yield Frame(k, last_t_s, image)
            k += 1

    def close(self) -> None:
        self._cap.release()

    def __str__(self) -> str:
        return f"camera {self.config.device!r}"
