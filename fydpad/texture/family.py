"""One interface for every texture family (issue 9): LPC, friction, grating, MLP.

A texture model takes the finger-state stream and produces signals on the output
channels it declares (:mod:`fydpad.channels.base`: ``"vibration"``, ``"tension"``,
``"audio"``). Two paths:

- ``render(finger, channel)``: offline, a whole :class:`FingerBlock` sampled at the
  channel's rate in, one array out (``fydpad texture synth|evaluate|identify``);
- ``tick(...)``: one 1 kHz step of the station's render loop, no allocation, returning
  the values of the 1 kHz channels named by ``tick_channels``, in that order.

Model files name their family in ``"kind"``; ``fydpad run --texture KIND:MODEL``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FingerBlock:
    """The finger state stream as equal-length arrays at one sample rate ``fs_hz``."""

    fs_hz: float
    t_s: Array
    contact: NDArray[np.bool_]
    x_mm: Array
    y_mm: Array
    speed_mm_s: Array
    force_n: Array

    def __post_init__(self) -> None:
        n = self.t_s.shape[0]
        for name in ("contact", "x_mm", "y_mm", "speed_mm_s", "force_n"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"FingerBlock.{name} must have shape ({n},), "
                                 f"got {getattr(self, name).shape}")


class TextureFamily(Protocol):
    """A fitted texture model of one family, ready to render."""

    #: "lpc", "friction", "grating" or "mlp".
    kind: str
    #: Declared output channels -> their native rate in Hz.
    channels: dict[str, float]
    #: The 1 kHz channels ``tick`` returns, in order (a subset of ``channels``).
    tick_channels: tuple[str, ...]

    def render(self, finger: FingerBlock, channel: str) -> Array:
        """The signal on ``channel`` for the whole block (sampled at ``finger.fs_hz``)."""

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float, ...]:
        """One render-loop step: the values of ``tick_channels``."""

    def reset(self) -> None:
        """Forget the signal history (a new stroke)."""


class TickPosition:
    """The finger's x between camera frames, for position-indexed families at 1 kHz.

    The station hands every tick the newest camera centroid (held between frames, ~30
    Hz), so indexing mu(x) or a grating by it would step every 33 ms. A new centroid is
    recognised by a change of value and stamped with the tick time (up to one tick
    late); between frames the position is extrapolated along the velocity over the last
    ``frames`` frames (a longer base than one frame: the 1-tick stamping jitter, 3 % of a
    33 ms frame, shrinks ``frames`` times), for at most ``hold_s``. A centroid that has
    not changed for ``stop_s`` (more than two frames at the paper's 10 Hz) is a finger at
    rest: the position is then the centroid itself, not where the last velocity would
    have carried it. No allocation.
    """

    def __init__(self, hold_s: float = 0.1, frames: int = 3, stop_s: float = 0.25) -> None:
        self.hold_s = hold_s
        self.stop_s = stop_s
        self.frames = frames
        self._ts = [0.0] * (frames + 1)
        self._xs = [0.0] * (frames + 1)
        self.reset()

    def reset(self) -> None:
        self._x = self._t = self._v = float("nan")
        self._n = 0

    def update(self, t_s: float, contact: bool, x_mm: float) -> float:
        """The estimated x (mm) now; NaN without contact."""
        if not contact or x_mm != x_mm:
            self.reset()
            return float("nan")
        if x_mm != self._x:
            m = self.frames + 1
            k = self._n % m
            self._ts[k], self._xs[k] = t_s, x_mm
            self._n += 1
            if self._n >= 2:
                back = min(self._n - 1, self.frames)
                j = (self._n - 1 - back) % m
                if t_s > self._ts[j]:
                    self._v = (x_mm - self._xs[j]) / (t_s - self._ts[j])
            self._x, self._t = x_mm, t_s
        dt = t_s - self._t
        if dt >= self.stop_s:
            self._v = 0.0  # no new centroid for a while: the finger has stopped
        return x_mm + (self._v * min(dt, self.hold_s) if self._v == self._v else 0.0)


def hold_finite(x: Array, first: float) -> Array:
    """``x`` with every non-finite sample replaced by the last finite one before it
    (``first`` before any): a missing load-cell reading holds the last one."""
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    if ok.all():
        return x
    idx = np.where(ok, np.arange(x.size), -1)
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx >= 0, x[np.maximum(idx, 0)], first)
