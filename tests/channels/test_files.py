import csv
import wave

import numpy as np
import pytest

from fydpad.channels import ChannelError, open_channel


def test_wav_blockwise_valid_and_clipping_counted(tmp_path):
    p = tmp_path / "v.wav"
    ch = open_channel(f"wav:{p}", 48000)
    x = np.sin(np.arange(1000) / 10.0) * 1.2
    ch.write(x[:400])
    with wave.open(str(p)) as r:  # valid before close
        assert r.getnframes() == 400 and r.getframerate() == 48000
    ch.write(x[400:])
    ch.close()
    ch.close()
    assert ch.n_clipped == int(np.count_nonzero(np.abs(x) > 1.0)) > 0
    with wave.open(str(p)) as r:
        pcm = np.frombuffer(r.readframes(r.getnframes()), "<i2") / 32767
    np.testing.assert_allclose(pcm, np.clip(x, -1, 1), atol=1 / 32767)


def test_wav_writes_nan_and_inf_as_zero_and_counts_them(tmp_path):
    p = tmp_path / "v.wav"
    with open_channel(f"wav:{p}", 1000) as ch:
        ch.write(np.array([0.5, np.nan, np.inf, -np.inf, -0.5]))
    assert ch.n_nonfinite == 3 and ch.n_clipped == 0
    with wave.open(str(p)) as r:
        pcm = np.frombuffer(r.readframes(r.getnframes()), "<i2")
    assert list(pcm) == [16384, 0, 0, 0, -16384]


def test_csv_channel(tmp_path):
    p = tmp_path / "v.csv"
    with open_channel(f"csv:{p}", 1000) as ch:
        ch.write(np.array([0.5, -0.25]))
        ch.write(np.array([1.0]))
    rows = list(csv.reader(open(p)))
    assert rows[0] == ["t_s", "vibration"]
    assert [float(r[0]) for r in rows[1:]] == [0.0, 0.001, 0.002]
    assert [float(r[1]) for r in rows[1:]] == [0.5, -0.25, 1.0]


def test_bad_specs_clear_error(tmp_path):
    with pytest.raises(ChannelError, match="expected wav:FILE"):
        open_channel("mp3:x", 1000)
    with pytest.raises(ChannelError, match="cannot open"):
        open_channel(f"wav:{tmp_path}/nope/x.wav", 1000)
    # audio's errors (no library, no PortAudio, no device): tests/channels/test_audio.py
