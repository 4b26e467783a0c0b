"""Output channels a texture renderer writes to, each at its own rate (issue 8)."""

from __future__ import annotations

from fydpad.channels.base import ChannelError, OutputChannel


def open_channel(spec: str, rate_hz: float, name: str = "vibration") -> OutputChannel:
    """Open ``wav:FILE``, ``csv:FILE`` or ``audio[:DEVICE]``; ChannelError says what to fix."""
    kind, _, arg = spec.partition(":")
    if kind == "wav" and arg:
        from fydpad.channels.files import WavChannel
        return WavChannel(arg, rate_hz, name)
    if kind == "csv" and arg:
        from fydpad.channels.files import CsvChannel
        return CsvChannel(arg, rate_hz, name)
    if kind == "audio":
        try:
            import sounddevice  # noqa: F401
        except (ImportError, OSError) as exc:
            raise ChannelError(
                f"audio channel: sounddevice/PortAudio unavailable ({exc}); install "
                "`pip install -e '.[audio]'` and libportaudio2, or choose a device with "
                "--audio-device") from exc
        raise ChannelError("audio channel: sound-card output is not implemented yet "
                           "(issue 8); use wav:FILE")
    raise ChannelError(f"channel spec {spec!r}: expected wav:FILE, csv:FILE or audio[:DEVICE]")
