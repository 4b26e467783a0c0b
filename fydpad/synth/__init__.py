"""The synthetic pad: pad session recordings rendered from the project's physical model.

Quick use::

    from fydpad.synth import SyntheticPad, SynthConfig, Effects
    pad = SyntheticPad(SynthConfig(trajectory="circle", seconds=5, seed=1))
    for frame_bgr, truth in pad.frames():   # raw camera frames, flipped per image_flip
        ...
    t_s, volts = pad.ir(); t_s, force_n = pad.force()
    pad.write("out/")                       # a docs/recording_format.md pad session recording
"""

from fydpad.synth.effects import EFFECT_HELP, Effects
from fydpad.synth.pad import FrameRenderer, FrameTruth, SynthConfig, SyntheticPad
from fydpad.synth.trajectory import TRAJECTORIES, FingerPath, TrajectoryParams, make_path

__all__ = [
    "EFFECT_HELP",
    "TRAJECTORIES",
    "Effects",
    "FingerPath",
    "FrameRenderer",
    "FrameTruth",
    "SynthConfig",
    "SyntheticPad",
    "TrajectoryParams",
    "make_path",
]
