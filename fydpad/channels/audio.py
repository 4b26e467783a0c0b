"""The audio-rate channel through the sound card: how PIEZOTACT (Felicetti 2022)
drives its piezo amplifier, and how voice-coil, piezo and electrostatic display
amplifiers are driven in haptics labs.

A PortAudio output stream (``sounddevice``, the optional extra ``audio``; PortAudio from
Debian's ``libportaudio2``) pulls samples in its callback from a bounded ring that the
renderer fills (:class:`fydpad.channels.ring.RingFeed`): ``write`` never blocks the 1 kHz
loop (a full ring drops and counts), an empty ring plays zeros and counts an underrun.
``write`` takes samples at ``rate_hz``, the renderer's rate (1 kHz, or a family's own);
they are resampled to the card's ``device_rate_hz`` (44.1 or 48 kHz) with state carried
across blocks. The stream is mono; with ``out_channels`` > 1 every channel gets it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.channels.base import ChannelError
from fydpad.channels.ring import RingFeed

INSTALL_HINT = ("install it with `pip install -e '.[audio]'` and PortAudio with "
                "`apt-get install libportaudio2`, or write to wav:FILE instead")
#: Card rates chosen without resampling when the renderer already runs at one of them.
AUDIO_RATES_HZ = (44100.0, 48000.0, 88200.0, 96000.0)
DEFAULT_DEVICE_RATE_HZ = 48000.0


def import_sounddevice() -> Any:
    """The ``sounddevice`` module, or ChannelError saying what is missing."""
    try:
        import sounddevice  # the optional extra ``audio``, loaded when a card is opened
    except ImportError as exc:
        raise ChannelError(f"audio channel: the sounddevice package is missing ({exc}); "
                           f"{INSTALL_HINT}") from None
    except OSError as exc:  # sounddevice imports, but cannot load the PortAudio library
        raise ChannelError(f"audio channel: PortAudio is missing ({exc}); "
                           f"{INSTALL_HINT}") from None
    return sounddevice


def output_devices(sd: Any) -> list[str]:
    """Names of the output devices PortAudio sees, ``index: name``."""
    return [f"{i}: {d['name']}" for i, d in enumerate(sd.query_devices())
            if d["max_output_channels"] > 0]


def resolve_output_device(sd: Any, device: str | int | None) -> tuple[int, str]:
    """(index, name) of the chosen output device (None or "default": the default one);
    ChannelError naming the device and listing the outputs there are."""
    if isinstance(device, str) and device.strip().isdigit():
        device = int(device)
    if device in (None, "", "default"):
        device = None
    try:
        info = sd.query_devices(device, "output")
    except (ValueError, sd.PortAudioError) as exc:
        outs = output_devices(sd)
        if not outs:
            raise ChannelError("audio channel: no audio output device on this machine "
                               "(PortAudio found none); connect a sound card or write to "
                               "wav:FILE") from None
        what = "the default output device" if device is None else f"device {device!r}"
        raise ChannelError(f"audio channel: {what}: {exc}; outputs here: "
                           f"{'; '.join(outs)} (`python -m sounddevice` lists them)") from None
    return int(info["index"]), str(info["name"])


class AudioChannel:
    """An :class:`~fydpad.channels.base.OutputChannel` on a sound card.

    The stream starts at open (``start=True``), playing silence until ``prefill_s`` of
    samples are buffered; ``buffer_s`` bounds the ring (and so the added latency).

    ``tap(frames)``, if given, is called in the callback with the frames just played from
    the ring (float32, full scale 1.0): for monitoring or recording what the card got.
    """

    def __init__(self, device: str | int | None = None, rate_hz: float = 1000.0,
                 device_rate_hz: float = DEFAULT_DEVICE_RATE_HZ, name: str = "audio",
                 full_scale: float = 1.0, buffer_s: float = 0.5, prefill_s: float = 0.02,
                 latency: str | float = "low", out_channels: int = 1,
                 tap: Callable[[NDArray[np.float32]], None] | None = None,
                 start: bool = True) -> None:
        sd = import_sounddevice()
        self.name = name
        self.rate_hz = float(rate_hz)
        self.device_rate_hz = float(device_rate_hz)
        self.device_index, self.device_name = resolve_output_device(sd, device)
        self.tap = tap
        self.n_device_underflows = 0  # PortAudio's own flag: the callback came too late
        label = f"{self.device_index}: {self.device_name}"
        try:
            sd.check_output_settings(device=self.device_index, samplerate=self.device_rate_hz,
                                     channels=out_channels, dtype="float32")
        except (ValueError, sd.PortAudioError) as exc:
            raise ChannelError(f"audio channel: device {label} cannot play {out_channels} "
                               f"channel(s) at {self.device_rate_hz:g} Hz ({exc})") from None
        try:
            self.feed = RingFeed(self.rate_hz, self.device_rate_hz,
                                 round(buffer_s * self.device_rate_hz),
                                 max(1, round(prefill_s * self.device_rate_hz)), full_scale)
        except ValueError as exc:
            raise ChannelError(f"audio channel: {exc}") from None
        try:
            self._stream = sd.OutputStream(
                device=self.device_index, samplerate=self.device_rate_hz,
                channels=out_channels, dtype="float32", latency=latency,
                callback=self._callback)
        except (ValueError, sd.PortAudioError) as exc:
            raise ChannelError(f"audio channel: cannot open device {label} ({exc})") from None
        self._sd = sd
        self._label = label
        self._closed = False
        if start:
            try:
                self.start()
            except ChannelError:
                self._stream.close()  # opened above: a failed open leaves nothing open
                raise

    def start(self) -> None:
        """Start the stream (``start=False`` at open: write a first block, then start)."""
        try:
            self._stream.start()
        except self._sd.PortAudioError as exc:
            raise ChannelError(f"audio channel: cannot start device {self._label} "
                               f"({exc})") from None

    # ------------------------------------------------------------------ callback side

    def _callback(self, outdata: NDArray[np.float32], frames: int, time_info: Any,
                  status: Any) -> None:
        if status.output_underflow:
            self.n_device_underflows += 1
        col = outdata[:, 0]
        n = self.feed.fill(col)
        if outdata.shape[1] > 1:
            outdata[:, 1:] = col[:, None]
        if self.tap is not None and n:
            self.tap(col[:n].copy())

    # ------------------------------------------------------------------ writer side

    def write(self, block: NDArray[np.float64]) -> None:
        """Queue samples at ``rate_hz``; never blocks (see ``stats`` for drops)."""
        if self._closed:
            raise ChannelError(f"audio channel {self._label}: write after close")
        self.feed.write(block)

    def play(self, signal: NDArray[np.float64], block_s: float = 0.01,
             timeout_s: float = 5.0) -> None:
        """Offline playback of a whole signal (a CLI, not the 1 kHz loop): writes it in
        blocks of ``block_s``, waiting for room in the ring instead of dropping."""
        x = np.asarray(signal, dtype=np.float64)
        step = max(1, round(block_s * self.rate_hz))
        need = int(np.ceil(step * self.device_rate_hz / self.rate_hz)) + 1
        for i in range(0, len(x), step):
            deadline = time.monotonic() + timeout_s
            while self.feed.ring.free < need:
                if time.monotonic() > deadline or not self._stream.active:
                    raise ChannelError(f"audio channel {self._label}: the device stopped "
                                       f"taking samples (unplugged?)")
                time.sleep(min(0.005, block_s / 2))
            self.write(x[i:i + step])

    @property
    def stats(self) -> dict[str, int]:
        f = self.feed
        return {"written": f.n_written, "played_frames": f.n_played,
                "dropped_frames": f.n_dropped, "clipped_frames": f.n_clipped,
                "nonfinite_samples": f.n_nonfinite,
                "underruns": f.n_underruns, "underrun_frames": f.n_underrun_frames,
                "device_underflows": self.n_device_underflows,
                "buffered_frames": f.ring.level}

    def close(self, drain: bool = True, timeout_s: float = 2.0) -> None:
        """Play out what is buffered (``drain``), then stop; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self.feed.draining = True
        if drain:
            deadline = time.monotonic() + timeout_s + self.feed.ring.level / self.device_rate_hz
            while self.feed.ring.level and self._stream.active and time.monotonic() < deadline:
                time.sleep(0.005)
        try:
            if drain:
                self._stream.stop()  # PortAudio plays out the buffers it already has
            else:
                self._stream.abort()  # the fail-safe path: silence now
        finally:
            self._stream.close()

    def __enter__(self) -> AudioChannel:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close(drain=exc_type is None)


def parse_audio_spec(spec: str, rate_hz: float) -> tuple[str | None, float]:
    """``audio[:DEVICE][@RATE]`` -> (device or None, card rate). Without ``@RATE`` the card
    runs at the renderer's ``rate_hz`` if that is an audio rate, else 48 kHz."""
    rest = spec[len("audio"):]
    if rest and rest[0] not in ":@":
        raise ChannelError(f"channel spec {spec!r}: expected audio[:DEVICE][@RATE]")
    rest = rest[1:] if rest.startswith(":") else rest
    device, at, rate = rest.rpartition("@") if "@" in rest else (rest, "", "")
    if at:
        try:
            card_hz = float(rate)
        except ValueError:
            card_hz = float("nan")
        if not card_hz > 0:
            raise ChannelError(f"channel spec {spec!r}: rate {rate!r} is not a positive "
                               "number of Hz (44100 or 48000)")
    else:
        card_hz = float(rate_hz) if float(rate_hz) in AUDIO_RATES_HZ else DEFAULT_DEVICE_RATE_HZ
    return (device or None), card_hz
