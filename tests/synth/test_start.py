"""A synthetic recording can start mid-session (``SynthConfig.start_s``), and a palm can
rest on the fabric at the start (``Effects(palm_rest=True)``)."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.synth import Effects, SynthConfig, SyntheticPad
from fydpad.synth.trajectory import START_STATES, start_time_s


def test_start_s_moves_the_recordings_clock_along_the_same_path():
    full = SyntheticPad(SynthConfig(trajectory="walk", seconds=6.0, seed=5))
    start = start_time_s(full.path, "down_moving")
    cut = SyntheticPad(SynthConfig(trajectory="walk", seconds=2.0, seed=5, start_s=start))
    k0 = round(start * 30.0)
    # Frame k of the cut recording is the full one's frame k0 + k (start on a frame).
    cut_on_frame = SyntheticPad(SynthConfig(trajectory="walk", seconds=2.0, seed=5,
                                            start_s=k0 / 30.0))
    for k in (0, 10, 40):
        a, b = cut_on_frame.truth(k), full.truth(k0 + k)
        assert a.t_s == pytest.approx(k / 30.0)
        assert (a.contact, a.x_mm, a.y_mm, a.indentation_mm) == pytest.approx(
            (b.contact, b.x_mm, b.y_mm, b.indentation_mm))
    tr = cut.truth(0)
    assert tr.contact and tr.indentation_mm >= 1.0
    assert cut.meta().extra["synthetic"]["start_s"] == start
    # The IR sees the finger pressing from the first sample.
    _, volts = cut.ir()
    rest = SyntheticPad(SynthConfig(trajectory="walk", seconds=2.0, seed=5)).ir()[1]
    assert np.mean(volts[:5]) > np.mean(rest[:5]) + 0.02  # closer fabric: higher volts


@pytest.mark.parametrize("state", START_STATES)
def test_start_time_finds_the_state(state):
    path = SyntheticPad(SynthConfig(trajectory="tapping" if state == "pressing" else "walk",
                                    seconds=12.0, seed=7)).path
    t = start_time_s(path, state)
    i = round(t / path.dt_s)
    assert path.z_mm[i] > 0.5
    speed = path.speed_mm_s()[i]
    if state == "down_still":
        assert speed < 2.0
    elif state == "down_moving":
        assert speed > 15.0
    else:
        assert np.gradient(path.z_mm, path.dt_s)[i] > 10.0


def test_no_such_state_is_refused():
    path = SyntheticPad(SynthConfig(trajectory="walk", seconds=3.0)).path
    with pytest.raises(ValueError, match="state must be one of"):
        start_time_s(path, "dancing")


def test_the_palm_rests_dark_and_sharp_at_the_start_then_lifts():
    cfg = SynthConfig(trajectory="walk", seconds=3.0, seed=6, effects=Effects(palm_rest=True),
                      mjpg_quality=None, read_noise=0.0, shot_gain=0.0)
    palm = SyntheticPad(cfg)
    bare = SyntheticPad(SynthConfig(trajectory="walk", seconds=3.0, seed=6, mjpg_quality=None,
                                    read_noise=0.0, shot_gain=0.0))
    ratio0 = (palm.frame(0).mean(axis=2) + 1) / (bare.frame(0).mean(axis=2) + 1)
    ratio_end = (palm.frame(85).mean(axis=2) + 1) / (bare.frame(85).mean(axis=2) + 1)
    assert ratio0.min() < 0.45  # blocks 60 % of the light where it rests
    area_mm2 = np.count_nonzero(ratio0 < 0.7) * (100.0 / 592) * (70.0 / 414)
    assert area_mm2 > 600  # a palm, far larger than a fingertip
    assert ratio_end.min() > 0.99  # lifted by 2.4 s
