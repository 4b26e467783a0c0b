"""``fydpad run --channel``: the station's texture signals on output channels.

A replayed blob circling the pad, the simulated motors and a friction model: the 1 kHz
vibration term goes to WAV and CSV files, the friction family's electrostatic channel
(V = b mu(x) Y(t), Jiao 2018 eq. 2) to a 48 kHz WAV. Checked against what the motors got
(the commands log), against the model (mu(x) at the positions the station saw, the 240 Hz
carrier) and against the contact in the session's track. The sound-card path runs the real
PortAudio stream on an ALSA null device in a child process (as tests/channels/test_audio.py).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import wave
from pathlib import Path

import numpy as np
import pytest

from fydpad.channels import ChannelError
from fydpad.cli import main
from fydpad.station.outputs import ChannelOutputs, parse_channel_spec
from fydpad.texture.families import load_family
from fydpad.texture.family import TickPosition
from tests.conftest import write_blob_recording
from vision.recording import read_track

ROOT = Path(__file__).resolve().parents[2]
ASOUNDRC = "pcm.!default { type null }\nctl.!default { type hw card 0 }\n"
B_V = 400.0  # the friction model's b (its default)


def read_wav(path: Path) -> tuple[int, np.ndarray]:
    with wave.open(str(path)) as w:
        rate, n = w.getframerate(), w.getnframes()
        pcm = np.frombuffer(w.readframes(n), "<i2").astype(float) / 32767
    return rate, pcm


@pytest.fixture(scope="module")
def circle_rec(tmp_path_factory) -> Path:
    rec = tmp_path_factory.mktemp("rec") / "circle"
    pos = ([None] * 6 + [(20 * np.cos(k / 8), 15 * np.sin(k / 8)) for k in range(30)]
           + [None] * 6 + [(-20 + k, 5.0) for k in range(15)] + [None] * 6)
    write_blob_recording(rec, pos)
    return rec


@pytest.fixture(scope="module")
def station_run(circle_rec: Path, friction_model: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run")
    rc = main(["run", "--replay", str(circle_rec), "--motors", "sim", "--texture",
               str(friction_model), "--channel", f"wav:{out / 'vib.wav'}",
               "--channel", f"csv:{out / 'vib.csv'}",
               "--channel", f"audio=wav:{out / 'V.wav'},fs=500",
               "--record", str(out / "session"), "--stats", str(out / "stats.json"),
               "--no-realtime"])
    assert rc == 0
    return out


def ticks(out: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per render tick: t_s, the vibration the motors got, and the frame's contact."""
    cmds = np.genfromtxt(out / "session" / "commands.csv", delimiter=",", names=True)
    track = read_track(out / "session" / "track.csv")
    contact = track["contact"][cmds["frame"].astype(int)] != 0
    return cmds["t_s"], cmds["vibration"], contact


def test_vibration_channel_is_what_the_motors_got_tick_for_tick(station_run: Path):
    t_s, vib, contact = ticks(station_run)
    rate, wav = read_wav(station_run / "vib.wav")
    assert rate == 1000 and len(wav) == len(t_s) > 500  # one sample per render tick
    # int16 of full scale 1.0 against the log's 6 decimals
    np.testing.assert_allclose(wav, np.clip(vib, -1, 1), atol=1 / 32767 + 1e-6)
    assert not np.any(wav[~contact])  # silent without contact
    assert np.count_nonzero(wav[contact]) > 0.8 * np.count_nonzero(contact)
    csv = np.genfromtxt(station_run / "vib.csv", delimiter=",", names=True)
    np.testing.assert_allclose(csv["t_s"], np.arange(len(t_s)) / 1000.0)
    np.testing.assert_allclose(csv["vibration"], vib, atol=1e-6)
    st = json.loads((station_run / "stats.json").read_text())["render"]["chain"]["channels"]
    assert st[f"wav:{station_run / 'vib.wav'}"]["samples"] == len(t_s)
    assert st[f"wav:{station_run / 'vib.wav'}"]["clipped"] == 0


def test_electrostatic_channel_is_b_mu_x_times_the_carrier(station_run: Path,
                                                           friction_model: Path):
    """48 samples per tick; zero without contact; with contact the 240 Hz 0/1 carrier times
    b mu(x), x where the station saw the finger in that tick (frame centroids extrapolated
    between frames, interpolated over the tick from the one before)."""
    t_s, _, contact = ticks(station_run)
    rate, v = read_wav(station_run / "V.wav")
    v *= 500.0  # fs=500: volts
    assert rate == 48000 and len(v) == 48 * len(t_s)
    per_tick = v.reshape(-1, 48)
    assert not np.any(per_tick[~contact])
    on = per_tick[contact] != 0
    assert 0.45 < on.mean() < 0.55  # the carrier's duty cycle
    # The positions the station saw: the frame's centroid per tick, as TickPosition makes it.
    cmds = np.genfromtxt(station_run / "session" / "commands.csv", delimiter=",", names=True)
    track = read_track(station_run / "session" / "track.csv")
    pos = TickPosition()
    xe = np.array([pos.update(t, bool(c), float(track["x_mm"][int(f)]) if c else math.nan)
                   for t, f, c in zip(t_s, cmds["frame"], contact, strict=True)])
    fam = load_family(str(friction_model))
    before = np.where(np.isfinite(np.roll(xe, 1)), np.roll(xe, 1), xe)
    # mu over the x swept in each tick (a new frame can move x a lot in one tick)
    sweep = fam.mu_at(np.nan_to_num(before[:, None] + (xe - before)[:, None]
                                     * np.linspace(0, 1, 101)[None, :]))
    lo, hi = sweep.min(axis=1) * B_V, sweep.max(axis=1) * B_V
    k = np.flatnonzero(contact)[1:]
    vals = np.where(per_tick[k] != 0, per_tick[k], np.nan)
    tol = 500 / 32767 + 0.01  # one LSB at fs=500, the logs' 6 decimals
    assert np.nanmin(vals - lo[k, None]) > -tol and np.nanmax(vals - hi[k, None]) < tol
    assert np.nanmax(vals) - np.nanmin(vals) > 100  # mu(x) swept 0.3..0.7 along the path
    # The carrier: its 0/1 pattern over the longest contact run has its line at 240 Hz.
    runs = np.flatnonzero(np.diff(np.concatenate([[0], contact, [0]]).astype(int)))
    a, b = max(zip(runs[::2], runs[1::2], strict=True), key=lambda r: r[1] - r[0])
    y = (per_tick[a + 1:b].ravel() != 0).astype(float)
    spec = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size)))
    f_peak = np.fft.rfftfreq(y.size, 1 / 48000)[np.argmax(spec)]
    assert abs(f_peak - 240.0) < 2.0


def test_blocks_of_any_size_write_the_same_files(friction_model: Path, tmp_path: Path):
    """The tick buffer and the per-block render: 1-, 7- and 10-tick blocks give identical
    files (the interpolation's tick before, the carrier's phase and the 48 kHz sample
    counts carry across blocks)."""
    from fydpad.station.chains import _TickModel

    model = _TickModel(str(friction_model), 1000.0)
    rng = np.random.default_rng(1)
    frames = np.repeat(np.cumsum(rng.uniform(0.5, 2.5, 40)), 33)[:1234]
    touch = (np.arange(frames.size) % 600) < 450
    files = {}
    for block in (1, 7, 10):
        d = tmp_path / str(block)
        d.mkdir()
        out = ChannelOutputs([f"wav:{d / 'vib.wav'}", f"audio=csv:{d / 'V.csv'}"],
                             [model], 1000.0, block)
        model.reset()
        for k, (x, c) in enumerate(zip(frames, touch, strict=True)):
            t = k / 1000.0
            vals = model.family.tick(t, bool(c), x, 0.0, 60.0, 0.5)
            out.tick(t, bool(c), x if c else math.nan, 0.0, 60.0, 0.5, 1.0, 0, vals, vals[0])
        out.close()
        files[block] = ((d / "vib.wav").read_bytes(), (d / "V.csv").read_text())
    assert files[1] == files[7] == files[10]
    v = np.genfromtxt(tmp_path / "1" / "V.csv", delimiter=",", names=True)
    assert v.size == 1234 * 48 and np.count_nonzero(v["audio"]) > 0


def test_a_live_b_reaches_the_electrostatic_channel(friction_model: Path, tmp_path: Path):
    """The staircase sets b while the station runs: the audio-rate channel (rendered by
    its own copy of the model) plays the new b, not the file's."""
    from fydpad.config import StationConfig
    from fydpad.station.render import RenderSpec, build_chain

    chain = build_chain(RenderSpec(motors="sim", texture=str(friction_model),
                                   channels=(f"audio=csv:{tmp_path / 'V.csv'}",),
                                   config=StationConfig(), realtime=False))
    chain.apply_control(0, 250.0)
    for k in range(200):
        chain.tick(k / 1000.0, True, 2.0 + 0.02 * k, 0.0, 20.0, 0.5, 1.0, 0.6)
    chain.safe_stop()
    v = np.genfromtxt(tmp_path / "V.csv", delimiter=",", names=True)["audio"]
    mu = chain.models[0].family.mu
    on = v[v > 0]
    assert on.size > 0
    # V = b mu(x) Y(t): with b = 250 (the file's default is 400) V stays within 250 mu.
    assert on.max() <= 250.0 * mu.max() + 1e-9 and on.min() >= 250.0 * mu.min() - 1e-9


def test_nan_b_gives_each_friction_model_its_files_b_again(friction_model: Path,
                                                          tmp_path: Path):
    """CONTROL_FIELDS: friction_b_v NaN means the file's b, also after a live b was set (the
    staircase done): each friction model, and the audio channel's copy, get their own."""
    from fydpad.config import StationConfig
    from fydpad.station.render import RenderSpec, build_chain

    data = json.loads(friction_model.read_text())
    other = tmp_path / "friction-300.json"
    other.write_text(json.dumps({**data, "electrostatic": {"b_v": 300.0}}))
    chain = build_chain(RenderSpec(motors="sim", texture=str(friction_model),
                                   textures=(str(other),),
                                   channels=(f"audio=csv:{tmp_path / 'V.csv'}",),
                                   config=StationConfig(), realtime=False))
    copies = chain.channels.routes[0].renderers

    def bs() -> list[float]:
        return [m.family.b for m in chain.models] + [r.b for r in copies]

    assert bs() == [B_V, 300.0, B_V, 300.0]  # as the files say
    chain.apply_control(0, 250.0)
    assert bs() == [250.0] * 4
    chain.apply_control(1, math.nan)
    assert bs() == [B_V, 300.0, B_V, 300.0]
    assert chain.live_stats()["friction_b_v"] == 300.0  # slot 1's own
    chain.apply_control(1, 250.0)  # the same b again after NaN: applied again
    assert bs() == [250.0] * 4
    chain.safe_stop()
    assert chain.faults == []


@pytest.mark.parametrize("text, signal, target, fs", [
    ("wav:out.wav", None, "wav:out.wav", 1.0),
    ("audio=wav:V.wav,fs=500", "audio", "wav:V.wav", 500.0),
    ("audio:hw:1,0@44100", None, "audio:hw:1,0@44100", 1.0),
    ("audio=audio:hw:1,0,fs=2", "audio", "audio:hw:1,0", 2.0),
    ("csv:a=b.csv", None, "csv:a=b.csv", 1.0),
])
def test_channel_specs(text, signal, target, fs):
    spec = parse_channel_spec(text)
    assert (spec.signal, spec.target, spec.full_scale) == (signal, target, fs)


@pytest.mark.parametrize("text", ["out.wav", "wav", "mp3:x.mp3", "wav:x.wav,fs=0",
                                  "audio=wav:x,fs=loud"])
def test_bad_channel_specs(text):
    with pytest.raises(ChannelError, match="--channel"):
        parse_channel_spec(text)


@pytest.mark.parametrize("argv, message", [
    (["--channel", "force=wav:{tmp}/f.wav"], "no texture renders 'force' (friction: "),
    (["--channel", "wav:/no/such/folder/v.wav"], "folder '/no/such/folder' is missing"),
    (["--channel", "out.wav"], "expected [SIGNAL=]TARGET"),
])
def test_bad_channels_are_one_line(argv, message, circle_rec, friction_model, tmp_path,
                                   capsys):
    argv = [a.format(tmp=tmp_path) for a in argv]
    assert main(["run", "--replay", str(circle_rec), "--motors", "sim", "--texture",
                 str(friction_model), *argv, "--no-realtime"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_channel_without_a_texture_is_one_line(circle_rec, tmp_path, capsys):
    assert main(["run", "--replay", str(circle_rec), "--channel", f"wav:{tmp_path}/v.wav",
                 "--no-realtime"]) == 2
    assert "--channel needs a texture" in capsys.readouterr().err


def test_station_plays_the_electrostatic_channel_on_the_sound_card(circle_rec, friction_model,
                                                                   tmp_path):
    """The real PortAudio stream (ALSA null device, child process): every tick's 48 samples
    reach the card's ring, and the callback plays them."""
    try:
        import sounddevice  # noqa: F401
    except (ImportError, OSError) as exc:
        pytest.skip(f"sounddevice/PortAudio not installed here ({exc})")
    home = tmp_path / "home"
    home.mkdir()
    (home / ".asoundrc").write_text(ASOUNDRC)
    stats = tmp_path / "stats.json"
    r = subprocess.run(
        [sys.executable, "-m", "fydpad.cli", "run", "--replay", str(circle_rec), "--motors",
         "sim", "--texture", str(friction_model), "--channel", "audio,fs=500",
         "--duration", "1.5", "--stats", str(stats), "--no-realtime"],
        env={**os.environ, "HOME": str(home), "PYTHONPATH": str(ROOT)}, capture_output=True,
        text=True, timeout=120, cwd=ROOT)
    if "no audio output device" in r.stderr or "cannot play" in r.stderr:
        pytest.skip(f"PortAudio cannot open an ALSA null device here: {r.stderr.strip()}")
    assert r.returncode == 0, r.stderr
    chain = json.loads(stats.read_text())["render"]["chain"]
    st = chain["channels"]["audio,fs=500"]
    assert st["signal"] == "audio" and st["rate_hz"] == 48000.0  # auto: friction's V
    assert st["samples"] == st["written"] == 48 * chain["ticks"]
    assert st["played_frames"] > 0 and st["clipped_frames"] == 0
