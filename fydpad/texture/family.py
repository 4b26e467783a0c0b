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
