"""The audio channel: its ring buffer and feed (pure), the real PortAudio callback path on
an ALSA null device (in a child process whose HOME has an ~/.asoundrc making the null
device the default), and the errors for a missing library, PortAudio or device.

Where sounddevice or PortAudio is not installed, the tests that need them skip and say so;
the missing-library errors are then tested by hiding the module (a boundary: the library
itself cannot be uninstalled for one test).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fydpad.channels import ChannelError, open_channel
from fydpad.channels.audio import parse_audio_spec
from fydpad.channels.resample import Resampler
from fydpad.channels.ring import RingFeed, SampleRing

PROBE = Path(__file__).with_name("audio_probe.py")
ASOUNDRC = "pcm.!default { type null }\nctl.!default { type hw card 0 }\n"


def sounddevice_or_skip():
    try:
        import sounddevice
    except (ImportError, OSError) as exc:
        pytest.skip(f"sounddevice/PortAudio not installed here ({exc})")
    return sounddevice


# --------------------------------------------------------------------------- ring, feed


def test_ring_wraps_drops_when_full_and_zero_fills_when_empty():
    r = SampleRing(8)
    assert r.push(np.arange(6.0)) == 6
    out = np.full(4, 9.0, np.float32)
    assert r.pop_into(out) == 4 and list(out) == [0, 1, 2, 3]
    assert r.push(np.arange(10.0, 20.0)) == 6  # 2 left + 6 = full; 4 dropped
    assert r.level == 8 and r.free == 0
    out = np.full(10, 9.0, np.float32)
    assert r.pop_into(out) == 8  # across the wrap, then zeros
    assert list(out) == [4, 5, 10, 11, 12, 13, 14, 15, 0, 0]
    assert r.level == 0
    with pytest.raises(ValueError, match="capacity"):
        SampleRing(0)


def test_feed_plays_the_resampled_signal_block_by_block():
    x = np.sin(np.arange(300) * 0.37) * 0.8
    feed = RingFeed(1000, 48000, capacity_frames=48000, prefill_frames=480)
    for k in range(len(x)):
        feed.write(x[k:k + 1])  # 1 ms blocks: the resampler's state carries over
    out = np.empty(len(x) * 48 + 100, np.float32)
    assert feed.fill(out) == len(x) * 48
    ref = Resampler(1000, 48000).process(x)  # the whole signal at once
    np.testing.assert_allclose(out[:len(ref)], ref, atol=1e-6)  # float32 on the card
    assert not np.any(out[len(ref):])
    assert feed.n_underruns == 1 and feed.n_underrun_frames == 100
    assert feed.n_dropped == feed.n_clipped == 0 and feed.n_played == len(ref)


def test_feed_waits_for_prefill_counts_underruns_and_drains():
    feed = RingFeed(48000, 48000, capacity_frames=1000, prefill_frames=100)
    assert feed.resampler is None  # same rate: no conversion
    out = np.ones(64, np.float32)
    assert feed.fill(out) == 0 and not out.any()
    assert feed.n_underrun_frames == 0  # nothing written yet: silence, not an underrun
    feed.write(np.full(99, 0.5))
    assert feed.fill(out) == 0 and feed.n_underrun_frames == 0  # below the prefill
    feed.write(np.full(1, 0.5))
    assert feed.fill(out) == 64 and np.all(out == 0.5)
    assert feed.fill(out) == 36 and feed.n_underruns == 1
    assert feed.n_underrun_frames == 28
    feed.write(np.full(50, 0.25))  # after an underrun it waits for the prefill again
    assert feed.fill(out) == 0 and feed.n_underrun_frames == 28 + 64
    feed.draining = True  # closing: play out what is left
    assert feed.fill(out) == 50 and np.all(out[:50] == 0.25) and not out[50:].any()
    assert feed.n_underruns == 1 and feed.n_played == 150


def test_feed_drops_when_full_and_clips_at_full_scale():
    feed = RingFeed(48000, 48000, capacity_frames=100, prefill_frames=10, full_scale=2.0)
    feed.write(np.linspace(-3, 3, 150))
    assert feed.n_dropped == 50 and feed.ring.level == 100
    x = np.linspace(-3, 3, 150)[:100] / 2.0
    assert feed.n_clipped == int(np.count_nonzero(np.abs(np.linspace(-3, 3, 150)) > 2.0))
    out = np.empty(100, np.float32)
    feed.fill(out)
    np.testing.assert_allclose(out, np.clip(x, -1, 1), atol=1e-7)
    with pytest.raises(ValueError, match="prefill"):
        RingFeed(1000, 48000, 10, 20)


@pytest.mark.parametrize("rate_in_hz", [48000.0, 1000.0])
def test_nan_and_inf_play_as_silence_and_are_counted(rate_in_hz):
    # abs(NaN) > 1 is False: without its own check NaN would pass the clip to the card,
    # and through the resampler's state it would spoil every block after it.
    feed = RingFeed(rate_in_hz, 48000, capacity_frames=48000, prefill_frames=1)
    x = np.sin(np.arange(200) * 0.3) * 0.5
    bad = x.copy()
    bad[[10, 50, 51]] = [np.nan, np.inf, -np.inf]
    for k in range(0, len(bad), 10):
        feed.write(bad[k:k + 10])
    out = np.empty(feed.ring.level, np.float32)
    feed.fill(out)
    assert feed.n_nonfinite == 3 and feed.n_written == 200 and feed.n_clipped == 0
    assert np.isfinite(out).all()
    clean = x.copy()
    clean[[10, 50, 51]] = 0.0
    ref = clean if feed.resampler is None else Resampler(rate_in_hz, 48000).process(clean)
    np.testing.assert_allclose(out, ref[:len(out)], atol=1e-6)


def test_audio_specs():
    assert parse_audio_spec("audio", 1000) == (None, 48000.0)
    assert parse_audio_spec("audio", 44100) == (None, 44100.0)  # already an audio rate
    assert parse_audio_spec("audio:hw:1,0", 1000) == ("hw:1,0", 48000.0)
    assert parse_audio_spec("audio:3@44100", 1000) == ("3", 44100.0)
    assert parse_audio_spec("audio@44100", 48000) == (None, 44100.0)
    with pytest.raises(ChannelError, match="rate 'fast'"):
        parse_audio_spec("audio@fast", 1000)
    with pytest.raises(ChannelError, match=r"audio\[:DEVICE\]\[@RATE\]"):
        parse_audio_spec("audiox", 1000)


# --------------------------------------------------------------------------- missing parts


def test_missing_sounddevice_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "sounddevice", None)  # as if not installed
    with pytest.raises(ChannelError, match=r"sounddevice package is missing.*\[audio\]"):
        open_channel("audio", 1000)


def test_missing_portaudio_is_a_clear_error(monkeypatch, tmp_path):
    # sounddevice raises OSError at import when it cannot load the PortAudio library.
    (tmp_path / "sounddevice.py").write_text(
        "raise OSError('PortAudio library not found')\n")
    monkeypatch.delitem(sys.modules, "sounddevice", raising=False)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ChannelError, match=r"PortAudio is missing.*libportaudio2"):
        open_channel("audio", 1000)
    monkeypatch.delitem(sys.modules, "sounddevice", raising=False)


def test_no_output_device_is_a_clear_error():
    sd = sounddevice_or_skip()
    from fydpad.channels.audio import output_devices

    if output_devices(sd):
        pytest.skip(f"this machine has audio outputs ({output_devices(sd)[0]}, ...)")
    with pytest.raises(ChannelError, match="no audio output device on this machine"):
        open_channel("audio", 1000)
    with pytest.raises(ChannelError, match="no audio output device"):
        open_channel("audio:speakers", 1000)


# --------------------------------------------------------------------------- real callback


MODEL = Path(__file__).resolve().parents[2] / "fydpad" / "texture" / "data" / "thesis_mlp.json"
PROBED = ("audio", "audio:default@44100", "audio:no-such-card", f"cli:{MODEL}",
          "start-fails:audio")


@pytest.fixture(scope="module")
def probed(tmp_path_factory) -> Path:
    """Run the probe once for every spec in PROBED; skip if PortAudio cannot open the null
    device here."""
    sounddevice_or_skip()
    tmp = tmp_path_factory.mktemp("audio")
    home = tmp / "home"
    home.mkdir()
    (home / ".asoundrc").write_text(ASOUNDRC)
    r = subprocess.run([sys.executable, str(PROBE), str(tmp), "300", *PROBED],
                       env={**os.environ, "HOME": str(home)}, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    if (tmp / "0" / "error.txt").exists():
        pytest.skip("PortAudio cannot open an ALSA null device here: "
                    + (tmp / "0" / "error.txt").read_text())
    return tmp


@pytest.mark.parametrize("i, rate_hz", [(0, 48000.0), (1, 44100.0)])
def test_written_samples_arrive_in_the_callback(probed, i, rate_hz):
    d = probed / str(i)
    st = json.loads((d / "stats.json").read_text())
    x = np.load(d / "written.npy")
    played = np.load(d / "played.npy")
    ref = Resampler(1000, rate_hz).process(x)  # what the 1 kHz signal is at the card's rate
    assert st["device_rate_hz"] == rate_hz and st["written"] == 300
    assert st["pushed_frames"] == len(ref) and st["played_frames"] == len(ref)
    assert len(played) == len(ref)
    np.testing.assert_allclose(played, ref, atol=1e-6)
    # the null device outruns the writer: the stream ran dry, and that was counted
    assert st["underruns"] >= 1 and st["underrun_frames"] > 0
    assert st["dropped_frames"] == 0 and st["clipped_frames"] == 0


def test_an_unknown_device_names_it_and_lists_the_outputs(probed):
    err = (probed / "2" / "error.txt").read_text()
    assert "device 'no-such-card'" in err and "0: default" in err


def test_texture_synth_plays_on_the_sound_card(probed):
    r = json.loads((probed / "3" / "cli.json").read_text())
    assert r["rc"] == 0, r["stderr"]
    # 0.3 s at the model's 1 kHz, resampled to 48 kHz
    assert "audio: played 14400 frames at 48000 Hz on default" in r["stdout"]


def test_a_stream_that_cannot_start_is_closed_again(probed):
    # PortAudio's start failing (a device taken by another program between open and
    # start) is injected in the probe: the null device always starts.
    r = json.loads((probed / "4" / "start_failure.json").read_text())
    assert r["error"].startswith("audio channel: cannot start device") and "injected" in \
        r["error"]
    assert r["streams"] == 1 and r["closed"] is True


def test_texture_synth_to_a_missing_card_is_a_one_line_error(capsys):
    from fydpad.cli import main

    # a card by a name no machine has: the error path on any machine, no sound made
    assert main(["texture", "synth", str(MODEL), "--speed-mm-s", "20", "--seconds", "0.1",
                 "--out", "audio:fydpad-no-such-card"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fydpad texture: error: audio channel:") and "\n" not in err
