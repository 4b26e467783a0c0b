"""Output channels of the live station: ``fydpad run --channel [SIGNAL=]TARGET``.

The render process's texture family writes, besides the motors' vibration term, to named
channels each at its own rate (docs/channels.md): ``vibration`` and ``tension`` come from
the family's 1 kHz ``tick`` (eq. 3's texture term before the chain compensation, which
belongs to the motors' chain only); a family's other declared channels (friction's
electrostatic ``audio`` V = b mu(x) Y(t) of Jiao 2018 eq. 2, a grating's ``audio`` V_e or
``force`` F_v of Ito 2019) are rendered at their own rate (48 kHz) by the family's
``render`` over each block, from the ticks' finger stream.

Nothing per tick but stores into preallocated arrays: every ``block_ticks`` ticks
(10 ms) the block is rendered and handed on. A sound card's ring write
(:class:`fydpad.channels.audio.AudioChannel`) never blocks; a file channel's block goes
into a preallocated ring that a thread of its own writes (:class:`FileWriter`), so the
1 kHz loop never waits on the disk.
On stop or fault (``close``) files get what was rendered and the sound card stops at once
(``abort``: silence, not a play-out of its buffer).
"""

from __future__ import annotations

import copy
import math
import os
import re
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fydpad.channels.audio import (
    AudioChannel,
    import_sounddevice,
    parse_audio_spec,
    resolve_output_device,
)
from fydpad.channels.base import ChannelError
from fydpad.channels.files import CsvChannel, WavChannel
from fydpad.channels.ring import SampleRing
from fydpad.texture.family import FingerBlock, TickPosition

#: The value of a signal with no texture, or a model without that channel.
NEUTRAL = {"tension": 1.0}
#: Signals the per-texture gain (and the vibration switch) does not scale: a stiffness
#: scale, not a vibration.
UNGAINED = frozenset({"tension"})
_FS = re.compile(r",fs=([^,=]+)$")


@dataclass(frozen=True)
class ChannelSpec:
    """One ``--channel``: which signal, where to, and its full scale (WAV, sound card)."""

    text: str
    #: ``vibration``, ``tension`` or a family channel (``audio``, ``force``); None: auto.
    signal: str | None
    #: ``wav:FILE``, ``csv:FILE`` or ``audio[:DEVICE][@RATE]`` (fydpad.channels.open_channel).
    target: str
    full_scale: float = 1.0

    @property
    def is_audio(self) -> bool:
        return self.target == "audio" or self.target.startswith(("audio:", "audio@"))


def parse_channel_spec(text: str) -> ChannelSpec:
    """``[SIGNAL=]TARGET[,fs=FULL_SCALE]``, e.g. ``wav:vib.wav``, ``audio=audio:hw:1,0@48000``,
    ``audio=wav:V.wav,fs=500``; ChannelError saying what is expected."""
    body, full_scale = text, 1.0
    m = _FS.search(body)
    if m:
        try:
            full_scale = float(m.group(1))
        except ValueError:
            full_scale = math.nan
        if not (full_scale > 0 and math.isfinite(full_scale)):
            raise ChannelError(f"--channel {text}: fs={m.group(1)} must be a positive full "
                               "scale (the signal's value that maps to 1.0)")
        body = body[:m.start()]
    signal, eq, target = body.partition("=")
    if not eq:
        signal, target = "", body
    # "=" inside a target (a file name) only counts as SIGNAL= when SIGNAL is a word.
    if eq and not re.fullmatch(r"[a-z_]+", signal):
        signal, target = "", body
    kind = target.partition(":")[0].partition("@")[0]
    if kind not in ("wav", "csv", "audio") or (kind in ("wav", "csv") and ":" not in target):
        raise ChannelError(f"--channel {text}: expected [SIGNAL=]TARGET with TARGET wav:FILE, "
                           "csv:FILE or audio[:DEVICE][@RATE]")
    return ChannelSpec(text, signal or None, target, full_scale)


def resolve_signal(spec: ChannelSpec, families: list[Any]) -> str:
    """The signal ``spec`` carries: its own, or (auto) a sound card gets the family's
    ``audio`` channel where the first texture declares one, anything else the vibration
    term. ChannelError when no loaded texture renders it."""
    fams = [f for f in families if f is not None]
    if not fams:
        raise ChannelError(f"--channel {spec.text}: no texture to render (--texture)")
    signal = spec.signal
    if signal is None:
        signal = "audio" if spec.is_audio and "audio" in fams[0].channels else "vibration"
    if not any(signal in f.channels for f in fams):
        kinds = "; ".join(f"{f.kind}: {', '.join(f.channels)}" for f in fams)
        raise ChannelError(f"--channel {spec.text}: no texture renders {signal!r} ({kinds})")
    return signal


def check_channel(text: str, families: list[Any], rate_hz: float = 1000.0) -> str:
    """Check a ``--channel`` before the station starts (the render process opens it):
    the spec, the signal, a file's folder, the sound card and its rate. Returns the
    signal; ChannelError names what is wrong."""
    spec = parse_channel_spec(text)
    signal = resolve_signal(spec, families)
    if spec.is_audio:
        first = next(f for f in families if f is not None and signal in f.channels)
        rate = rate_hz if signal in ("vibration", "tension") else first.channels[signal]
        device, card_hz = parse_audio_spec(spec.target, rate)
        sd = import_sounddevice()
        index, name = resolve_output_device(sd, device)
        try:
            sd.check_output_settings(device=index, samplerate=card_hz, channels=1,
                                     dtype="float32")
        except (ValueError, sd.PortAudioError) as exc:
            raise ChannelError(f"--channel {text}: device {index}: {name} cannot play "
                               f"{card_hz:g} Hz ({exc})") from None
    else:
        folder = Path(spec.target.partition(":")[2]).parent
        if not folder.is_dir() or not os.access(folder, os.W_OK):
            raise ChannelError(f"--channel {text}: folder {str(folder)!r} is missing or not "
                               "writable")
    return signal


class FileWriter:
    """A file channel written by its own thread: ``write`` copies the block into a
    preallocated ring (:class:`fydpad.channels.ring.SampleRing`, ``buffer_s`` of samples)
    and returns; no allocation, no wait. A disk stalled past the ring drops samples,
    counted in ``stats`` (``dropped_samples``).

    The thread owns the channel: it writes what the ring holds, in order, every
    ``poll_s``, and closes the channel after the last write, so a close never lands in
    the middle of a write (a slow disk).
    """

    def __init__(self, channel: Any, buffer_s: float = 2.5, poll_s: float = 0.02) -> None:
        self.channel = channel
        self.name, self.rate_hz = channel.name, channel.rate_hz
        self.ring = SampleRing(max(1, math.ceil(buffer_s * channel.rate_hz)), np.float64)
        self.poll_s = float(poll_s)
        #: The first failed write (the thread stops writing then), and a failed close.
        self.error: BaseException | None = None
        self.close_error: BaseException | None = None
        self._reported = False  # ``error`` already raised by ``write``
        self._discard = False  # close(drain=False): drop the samples still buffered
        self._stop = threading.Event()
        #: Samples that did not fit (a stalled disk) and, on close(drain=False), those
        #: still buffered.
        self.dropped = 0
        self.discarded = 0
        self._thread = threading.Thread(target=self._run, name=f"channel-{self.name}",
                                        daemon=True)
        self._thread.start()

    def _run(self) -> None:
        chunk = np.empty(max(1, min(self.ring.capacity, 4096)))
        while True:
            stopping = self._stop.is_set()
            if self._discard:
                n = self.ring.pop_into(chunk)
                self.discarded += n
                if n:
                    continue
            else:
                n = self.ring.pop_into(chunk)
                if n:
                    if self.error is None:
                        try:
                            self.channel.write(chunk[:n])
                        except BaseException as exc:  # reported by ``write``/``close``
                            self.error = exc
                    time.sleep(0)  # a waiting tick takes the GIL between chunks
                    continue
            if stopping:
                break
            self._stop.wait(self.poll_s)
        try:
            self.channel.close()  # here, after the last write: never during one
        except BaseException as exc:
            self.close_error = exc

    def write(self, block: np.ndarray) -> None:
        if self.error is not None:
            self._reported = True
            raise ChannelError(f"write failed: {self.error}")
        if self._stop.is_set():
            raise ChannelError("write after close")
        self.dropped += len(block) - self.ring.push(block)

    def close(self, drain: bool = True, timeout_s: float = 10.0) -> None:
        """``drain``: write the samples still buffered first (a file keeps what was
        rendered); else drop them (counted in ``discarded``). The thread closes the
        channel after its last write. ChannelError (one line) for a write failure not yet
        raised by ``write``, a failed close (a WAV header not finalised), or a write still
        running after ``timeout_s`` (the channel is then closed when it returns)."""
        if not drain:
            self._discard = True
        self._stop.set()
        self._thread.join(timeout=timeout_s)
        if self._thread.is_alive():
            raise ChannelError(f"still writing after {timeout_s:g} s; closed once that "
                               "write returns")
        problems = []
        if self.error is not None and not self._reported:
            self._reported = True
            problems.append(f"write failed: {self.error}")
        if self.close_error is not None:
            problems.append(f"close failed: {self.close_error}")
        if problems:
            raise ChannelError("; ".join(problems))

    @property
    def stats(self) -> dict:
        out = {"written": int(getattr(self.channel, "n_written", 0))}
        if hasattr(self.channel, "n_clipped"):
            out["clipped"] = int(self.channel.n_clipped)
        if getattr(self.channel, "n_nonfinite", 0):
            out["nonfinite"] = int(self.channel.n_nonfinite)
        out["dropped_samples"] = self.dropped
        if self.discarded:
            out["discarded_samples"] = self.discarded
        if self.error is not None:
            out["error"] = str(self.error)
        if self.close_error is not None:
            out["close_error"] = str(self.close_error)
        return out


def open_target(spec: ChannelSpec, rate_hz: float, signal: str) -> Any:
    """The channel for ``spec`` taking ``signal`` at ``rate_hz``: a sound card (resampled to
    its rate) or a file written at ``rate_hz`` by a thread."""
    kind, _, arg = spec.target.partition(":")
    if spec.is_audio:
        device, card_hz = parse_audio_spec(spec.target, rate_hz)
        return AudioChannel(device, rate_hz, card_hz, signal, full_scale=spec.full_scale)
    if kind == "wav":
        return FileWriter(WavChannel(arg, rate_hz, signal, full_scale=spec.full_scale))
    return FileWriter(CsvChannel(arg, rate_hz, signal))


class _Route:
    """One channel: where its signal comes from, for each texture model."""

    def __init__(self, spec: ChannelSpec, signal: str, models: list[Any], tick_rate_hz: float):
        self.spec, self.signal = spec, signal
        self.gained = signal not in UNGAINED
        self.neutral = NEUTRAL.get(signal, 0.0)
        fams = [None if m is None else m.family for m in models]
        first = next(f for f in fams if f is not None and signal in f.channels)
        in_tick = [f is not None and signal in f.tick_channels for f in fams]
        #: From the tick's values (1 kHz), else rendered per block at the family's rate.
        self.from_tick = signal == "vibration" or any(in_tick)
        if self.from_tick:
            self.rate_hz = tick_rate_hz
            self.tick_index = [f.tick_channels.index(signal) if ok else -1
                               for f, ok in zip(fams, in_tick, strict=True)]
            self.renderers: list[Any] = []
        else:
            self.rate_hz = float(first.channels[signal])
            # A copy of each family: ``render`` may keep state (the MLP's filters) that
            # must not be the tick's.
            self.renderers = [copy.deepcopy(f) if f is not None and signal in f.channels
                              else None for f in fams]
            for r in self.renderers:
                if r is not None:
                    r.reset()
        #: Each renderer's b as its file gives it (None: no b), for a live b set back.
        self.file_b = [r.parameters.get("b_v") if r is not None else None
                       for r in self.renderers]
        self.out: Any = None
        self.n_samples = 0  # samples handed to the channel
        #: Why this channel stopped taking blocks (one line naming it), or None.
        self.failed: str | None = None


class ChannelOutputs:
    """The render loop's output channels: ``tick`` once per tick, ``close`` at the end."""

    def set_friction_b(self, b_v: float) -> None:
        """A new electrostatic gain b (the staircase's; NaN: each file's own) for the block
        renderers' copies of friction models too: the audio channel is where b is felt."""
        for route in self.routes:
            for r, file_b in zip(route.renderers, route.file_b, strict=True):
                if file_b is not None:
                    r.set_parameter("b_v", b_v if b_v == b_v else file_b)

    def __init__(self, specs: list[str], models: list[Any], rate_hz: float,
                 block_ticks: int = 10) -> None:
        if block_ticks < 1:
            raise ValueError(f"channel block must be at least one tick, not {block_ticks}")
        self.rate_hz = float(rate_hz)
        self.block_ticks = int(block_ticks)
        fams = [None if m is None else m.family for m in models]
        self.routes: list[_Route] = []
        self.close_errors: list[str] = []
        try:
            for text in specs:
                spec = parse_channel_spec(text)
                signal = resolve_signal(spec, fams)
                route = _Route(spec, signal, models, self.rate_hz)
                route.out = open_target(spec, route.rate_hz, signal)
                self.routes.append(route)
        except BaseException:
            self.close()
            raise
        n = self.block_ticks + 1  # slot 0: the last tick of the block before
        self._t = np.zeros(n)
        self._contact = np.zeros(n, bool)
        self._x = np.full(n, np.nan)
        self._y = np.full(n, np.nan)
        self._speed = np.zeros(n)
        self._force = np.zeros(n)
        self._gain = np.zeros(n)
        self._model = np.full(n, -1, np.int64)
        self._vals = np.zeros((len(self.routes), n))
        self._xpos, self._ypos = TickPosition(), TickPosition()
        self._i = 1
        self._ticks = 0  # ticks flushed so far
        self._t_start = math.nan
        self.closed = False

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float, speed_mm_s: float,
             force_n: float, gain: float, model: int, values: tuple | None,
             vibration: float) -> None:
        """Store one tick: the finger, the gain, the model in use and its tick ``values``
        (None: no texture); ``vibration`` is its vibration term before compensation."""
        i = self._i
        self._t[i] = t_s
        self._contact[i] = contact
        self._x[i] = self._xpos.update(t_s, contact, x_mm)
        self._y[i] = self._ypos.update(t_s, contact, y_mm)
        self._speed[i] = speed_mm_s
        self._force[i] = force_n
        self._gain[i] = gain
        self._model[i] = model if values is not None else -1
        for r, route in enumerate(self.routes):
            if route.from_tick:
                if values is None:
                    v = route.neutral
                elif route.signal == "vibration":
                    v = vibration
                else:
                    j = route.tick_index[model]
                    v = values[j] if j >= 0 else route.neutral
                self._vals[r, i] = v * gain if route.gained else v
        self._i = i + 1
        if i == self.block_ticks:
            self.flush()

    def flush(self) -> None:
        """Render and hand on the ticks stored since the last flush. A channel that fails
        (its file's disk, its model's render) is reported once, in one line naming it, and
        takes no more blocks; the others get theirs; then ChannelError."""
        n = self._i - 1
        if n <= 0 or self.closed:
            return
        if self._ticks == 0:
            self._t_start = float(self._t[1])
        failed = []
        for r, route in enumerate(self.routes):
            if route.failed is not None:
                continue
            try:
                block = (self._vals[r, 1:n + 1] if route.from_tick
                         else self._render(route, n))
                route.out.write(block)
            except Exception as exc:
                route.failed = f"channel {route.spec.text}: {exc}".splitlines()[0]
                failed.append(route.failed)
                continue
            route.n_samples += len(block)
        self._ticks += n
        for a in (self._t, self._contact, self._x, self._y, self._speed, self._force,
                  self._gain, self._model):
            a[0] = a[n]
        self._vals[:, 0] = self._vals[:, n]
        self._i = 1
        if failed:
            raise ChannelError("; ".join(failed))

    def _render(self, route: _Route, n: int) -> np.ndarray:
        """The block at the route's rate: sample j (since start) sits at tick u = j r / R;
        it takes the finger of tick floor(u), x and y interpolated from the tick before
        (one tick late, so the block needs no tick after it)."""
        ratio = route.rate_hz / self.rate_hz
        j0 = math.floor(self._ticks * ratio)
        j1 = math.floor((self._ticks + n) * ratio)
        j = np.arange(j0, j1)
        u = j / ratio - self._ticks  # ticks into the block, [0, n)
        b = np.minimum(u.astype(np.int64), n - 1) + 1  # buffer slot of the tick
        frac = u - (b - 1)

        def lerp(a: np.ndarray) -> np.ndarray:
            lo, hi = a[b - 1], a[b]
            return np.where(np.isfinite(lo), lo + (hi - lo) * frac, hi)

        out = np.full(j.size, route.neutral)
        model = self._model[b]
        for m in np.unique(model):
            fam = route.renderers[m] if m >= 0 else None
            if fam is None:
                continue
            sel = model == m
            finger = FingerBlock(route.rate_hz, self._t_start + j[sel] / route.rate_hz,
                                 self._contact[b[sel]], lerp(self._x)[sel],
                                 lerp(self._y)[sel], self._speed[b[sel]], self._force[b[sel]])
            out[sel] = fam.render(finger, route.signal)
        if route.gained:
            out *= self._gain[b]
        return out

    def stats(self) -> dict:
        """Per channel: its target, signal, rate, samples written and its own counters."""
        out = {}
        for route in self.routes:
            st = dict(route.out.stats) if route.out is not None else {}
            out[route.spec.text] = {"signal": route.signal, "rate_hz": route.rate_hz,
                                    "samples": route.n_samples, **st}
            if route.failed is not None:
                out[route.spec.text]["failed"] = route.failed
        return out

    def close(self) -> list[str]:
        """Stop or fault: files get what was rendered, a sound card goes silent now. Every
        channel is closed whatever the others do; returns the failures seen here (also
        kept in ``close_errors``), one line each naming the channel. Never raises."""
        if getattr(self, "closed", False):
            return []
        errors: list[str] = []
        if hasattr(self, "_i"):
            try:
                self.flush()
            except Exception as exc:  # each failed channel, named once, in one line
                errors.append(str(exc))
        self.closed = True
        for route in getattr(self, "routes", ()):
            if route.out is None:
                continue
            try:
                # A file is drained (it keeps what was rendered); a card stops at once.
                route.out.close(drain=not route.spec.is_audio)
            except Exception as exc:
                line = f"channel {route.spec.text}: {exc}".splitlines()[0]
                route.failed = route.failed or line
                errors.append(line)
        self.close_errors = errors
        return errors
