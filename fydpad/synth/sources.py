"""The synthetic pad behind vision's device interfaces (``FrameSource``, ``IRSource``,
``ForceSource``), so the station, ``track`` and tests run on it as on a real pad."""

from __future__ import annotations

import time
from collections.abc import Iterator

from fydpad.synth.pad import SyntheticPad
from vision.sensors import ReplayForce, ReplayIR
from vision.sources import Frame


class SynthFrameSource:
    """Raw camera frames of a synthetic pad, rendered on demand (a ``FrameSource``).

    ``realtime=True`` paces the frames at the camera rate from the first one, as a live
    camera would deliver them; otherwise they come as fast as they render.
    """

    def __init__(self, pad: SyntheticPad, realtime: bool = False):
        self.pad = pad
        self.fps = pad.cfg.fps
        self.frame_size = pad.cfg.frame_size
        self.realtime = realtime
        self._closed = False

    def frames(self) -> Iterator[Frame]:
        start = time.monotonic()
        for k in range(self.pad.frame_count):
            if self._closed:
                return
            t_s = k / self.fps
            if self.realtime:
                delay = start + t_s - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            yield Frame(k, t_s, self.pad.frame(k))

    def close(self) -> None:
        self._closed = True


def synth_ir_source(pad: SyntheticPad) -> ReplayIR:
    """The pad's IR board samples as an ``IRSource``."""
    t, v = pad.ir()
    return ReplayIR(t, v)


def synth_force_source(pad: SyntheticPad) -> ReplayForce:
    """The pad's load-cell samples as a ``ForceSource``."""
    return ReplayForce(*pad.force())
