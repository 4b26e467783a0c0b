"""Output channels a texture renderer writes to, each at its own rate."""

from __future__ import annotations

from fydpad.channels.base import ChannelError, OutputChannel
from fydpad.channels.files import CsvChannel, WavChannel


def open_channel(spec: str, rate_hz: float, name: str = "vibration") -> OutputChannel:
    """Open ``wav:FILE``, ``csv:FILE`` (written at ``rate_hz``) or ``audio[:DEVICE][@RATE]``
    (the sound card: fed at ``rate_hz``, played at RATE, default 48 kHz, through
    fydpad.channels.resample). ChannelError says what to fix."""
    kind, _, arg = spec.partition(":")
    if kind == "wav" and arg:
        return WavChannel(arg, rate_hz, name)
    if kind == "csv" and arg:
        return CsvChannel(arg, rate_hz, name)
    if kind == "audio" or spec.startswith("audio@"):
        # lazy: the card's resampler loads scipy.signal
        from fydpad.channels.audio import AudioChannel, parse_audio_spec

        # ``rate_hz`` is the renderer's; the card runs at its own rate (resampled).
        device, card_hz = parse_audio_spec(spec, rate_hz)
        return AudioChannel(device, rate_hz, card_hz, name)
    raise ChannelError(f"channel spec {spec!r}: expected wav:FILE, csv:FILE or "
                       "audio[:DEVICE][@RATE]")
