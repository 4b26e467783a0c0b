"""The output-channel interface.

A renderer produces a signal at its own rate; a channel consumes blocks at the
channel's rate (``rate_hz``). Between the two, :mod:`fydpad.channels.resample`
converts with a polyphase filter whose state is carried across blocks.

Channel names in use:

- ``"vibration"``: the FYD-pad motors' vibration term of eq. (3), 1 kHz;
- ``"tension"``: a fabric-tension modulation (a scale on the softness stiffness), 1 kHz;
- ``"audio"``: an audio-rate drive (44.1 or 48 kHz) for voice-coil, piezo or
  electrostatic display amplifiers, through the sound card;
- file export (WAV, CSV) of any of them.
"""

from __future__ import annotations

from types import TracebackType
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from vision.errors import DeviceFault

#: The channels the FYD-pad itself drives from the 1 kHz render loop.
VIBRATION = "vibration"
TENSION = "tension"
AUDIO = "audio"


def zero_nonfinite(block: NDArray[np.floating]) -> tuple[NDArray[np.float64], int]:
    """(the block as float64 with NaN and +-inf set to 0, how many were). A non-finite
    sample passes a clip test (``abs(NaN) > 1`` is False) and would reach the output."""
    x = np.asarray(block, dtype=np.float64)
    bad = ~np.isfinite(x)
    n = int(np.count_nonzero(bad))
    return (np.where(bad, 0.0, x) if n else x), n


class ChannelError(DeviceFault, RuntimeError):
    """A channel that cannot be opened or written; the message says what to check."""

    device = "channel"
    check = "the --channel spec (wav:FILE, csv:FILE or audio[:DEVICE][@RATE])"


class OutputChannel(Protocol):
    """Something that consumes a signal at ``rate_hz``."""

    name: str
    rate_hz: float

    def write(self, block: NDArray[np.float64]) -> None:
        """Consume the next samples (already at ``rate_hz``)."""

    def close(self) -> None:
        """Flush and release; safe to call twice."""

    def __enter__(self) -> OutputChannel: ...

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None: ...
