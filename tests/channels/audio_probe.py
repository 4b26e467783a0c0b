"""Run by tests/channels/test_audio.py in a child process whose HOME holds an ALSA config
with a null default device: writes a signal to the real AudioChannel (PortAudio stream,
real callback) and saves what the callback played and the channel's counters.

    python tests/channels/audio_probe.py OUT_DIR N SPEC [SPEC ...]

For each SPEC (the renderer at 1 kHz, N samples) it writes OUT_DIR/<i>/: played.npy,
written.npy, stats.json; or error.txt with the ChannelError when the channel cannot be
opened. A SPEC ``cli:MODEL.json`` instead runs ``fydpad texture synth MODEL.json
--speed-mm-s 20 --seconds 0.3 --out audio`` and saves its exit code and output in
cli.json. A SPEC ``start-fails:SPEC`` opens SPEC with PortAudio's stream start failing
(injected: the null device always starts) and saves the error and whether the stream was
closed in start_failure.json. One process for all: starting Python with scipy costs
seconds here.

The ALSA null device takes samples as fast as the callback gives them (it has no clock),
so after the signal has played the stream runs dry: underruns must then be counted.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from fydpad.channels import ChannelError
from fydpad.channels.audio import AudioChannel, parse_audio_spec


def signal(n: int) -> np.ndarray:
    """A chirp and a tone below the renderer's Nyquist, inside full scale."""
    t = np.arange(n) / 1000.0
    return 0.5 * np.sin(2 * np.pi * (20 + 200 * t) * t) + 0.3 * np.sin(2 * np.pi * 90 * t)


def probe(spec: str, n: int, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    played: list[np.ndarray] = []
    try:
        device, card_hz = parse_audio_spec(spec, 1000.0)
        # Not started yet: the null device would spin the callback while we write, and on a
        # loaded 2-core machine the two threads then queue for the GIL for seconds.
        ch = AudioChannel(device, 1000.0, card_hz, tap=played.append, start=False)
    except ChannelError as exc:
        (out / "error.txt").write_text(str(exc))
        return
    x = signal(n)
    for k in range(n):  # one sample per 1 ms tick, as the render loop writes
        ch.write(x[k:k + 1])
    pushed = ch.feed.ring._w
    ch.start()
    deadline = time.monotonic() + 10.0
    while (ch.feed.n_played < pushed or ch.feed.n_underruns == 0) \
            and time.monotonic() < deadline:
        time.sleep(0.005)
    ch.close()
    np.save(out / "played.npy", np.concatenate(played) if played else np.zeros(0))
    np.save(out / "written.npy", x)
    (out / "stats.json").write_text(json.dumps(
        {**ch.stats, "pushed_frames": pushed, "device_rate_hz": ch.device_rate_hz,
         "device_name": ch.device_name}))


def probe_start_failure(spec: str, out: Path) -> None:
    import sounddevice as sd

    out.mkdir(parents=True, exist_ok=True)
    streams: list = []
    real = sd.OutputStream

    class StartFails(real):  # the real stream, opened on the device; only start fails
        def __init__(self, *args, **kw) -> None:
            super().__init__(*args, **kw)
            streams.append(self)

        def start(self) -> None:
            raise sd.PortAudioError("injected: Device unavailable")

    sd.OutputStream = StartFails
    error = ""
    try:
        device, card_hz = parse_audio_spec(spec, 1000.0)
        AudioChannel(device, 1000.0, card_hz).close()
    except ChannelError as exc:
        error = str(exc)
    finally:
        sd.OutputStream = real
    (out / "start_failure.json").write_text(json.dumps(
        {"error": error, "streams": len(streams),
         "closed": bool(streams) and bool(streams[0].closed)}))


def run_cli(model: str, out: Path) -> None:
    import contextlib
    import io

    from fydpad.cli import main as fydpad_main

    out.mkdir(parents=True, exist_ok=True)
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        rc = fydpad_main(["texture", "synth", model, "--speed-mm-s", "20", "--seconds", "0.3",
                          "--out", "audio"])
    (out / "cli.json").write_text(json.dumps(
        {"rc": rc, "stdout": stdout.getvalue(), "stderr": stderr.getvalue()}))


def main() -> int:
    out_dir, n = Path(sys.argv[1]), int(sys.argv[2])
    for i, spec in enumerate(sys.argv[3:]):
        if spec.startswith("cli:"):
            run_cli(spec[4:], out_dir / str(i))
        elif spec.startswith("start-fails:"):
            probe_start_failure(spec[len("start-fails:"):], out_dir / str(i))
        else:
            probe(spec, n, out_dir / str(i))
    return 0


if __name__ == "__main__":
    sys.exit(main())
