"""Test pads unlike the default one, for the indentation calibration: a stiffer and a
softer fabric (tension and how far the sag spreads across the stretch), a different sag
shape (shorter span between the rollers, a sag that narrows and widens more with
depth) and IR sensors mounted off the places the recording states.

``indentation_samples`` gives what ``fydpad calibrate indentation`` fits on, from a
synthetic session's IR and truth (no video needed): the plane estimate, the sensors'
deflections (the causal filter's readings, as ``fydpad track`` applies the correction
to), the true centroid and depth over the contact frames with valid readings.
``calibrate`` fits the correction on sessions of a pad as ``fydpad calibrate
indentation`` does (by default one run of the calibration protocol, the ``protocol``
trajectory: what a user records); ``causal_indentation`` is what ``fydpad track`` gives
with a correction, frame by frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fydpad.fabric import Fabric
from fydpad.synth.pad import SynthConfig, SyntheticPad
from fydpad.synth.sensors import IRParams
from fydpad.synth.trajectory import protocol_duration_s
from vision.indentation import IndentationEstimator, SagCorrection, indentation_at_frames
from vision.stream import CausalIndentation

#: name -> SynthConfig fields of the pad.
TEST_PADS: dict[str, dict[str, Any]] = {
    "default": {},
    "stiffer": {"fabric": Fabric(tension_rest_n=18.0, axial_n_per_mm=1.6, decay_mm=42.0,
                                 decay_per_mm_depth=0.2)},
    "softer": {"fabric": Fabric(tension_rest_n=5.0, axial_n_per_mm=0.5, decay_mm=20.0,
                                decay_per_mm_depth=0.5)},
    "sag_shape": {"fabric": Fabric(span_mm=120.0, decay_mm=16.0, decay_per_mm_depth=0.8)},
    "sensors_off": {"ir": IRParams(position_error_mm=((3.0, -2.0), (-2.5, 3.0),
                                                      (2.0, 2.5)))},
}


#: The calibration a user does: one run of the protocol (``fydpad calibrate indentation
#: --protocol``, three recordings, 36 presses).
PROTOCOL_SESSIONS: tuple[tuple[str, int], ...] = (("protocol", 101),)


def session_seconds(trajectory: str) -> float:
    """20 s, or for the protocol as long as the synthetic hand takes to follow it."""
    return protocol_duration_s() + 1.0 if trajectory == "protocol" else 20.0


def indentation_samples(pad_name: str, trajectory: str, seed: int,
                        seconds: float | None = None, fps: float = 30.0
                        ) -> dict[str, np.ndarray]:
    """Contact frames of a session on a test pad: ``plane``, ``e`` (n, 3), ``x``, ``y``,
    ``depth`` (truth) and ``press`` (the number of the contact each frame is in);
    ``sensors`` the sensor positions the recording states. ``seconds``: by default
    ``session_seconds``."""
    seconds = session_seconds(trajectory) if seconds is None else seconds
    pad = SyntheticPad(SynthConfig(trajectory=trajectory, seconds=seconds, seed=seed,
                                   fps=fps, **TEST_PADS[pad_name]))
    t_ir, volts = pad.ir()
    truth = [pad.truth(k) for k in range(pad.frame_count)]
    t = np.array([q.t_s for q in truth])
    c = np.array([q.contact for q in truth])
    x = np.array([q.x_mm for q in truth])
    y = np.array([q.y_mm for q in truth])
    depth = np.array([q.indentation_mm for q in truth])
    m = pad.meta()
    est = IndentationEstimator(sensors_mm=m.ir_sensors_mm, base_to_fabric_mm=m.base_to_fabric_mm)
    r, _ = indentation_at_frames(est, t_ir, volts, t, c, x, y)
    ok = c & r.valid
    press = np.cumsum(np.diff(np.concatenate([[0], c.astype(int)])) == 1)
    assert r.deflection_mm is not None
    return {"plane": r.plane_mm[ok], "e": r.deflection_mm[ok], "x": x[ok], "y": y[ok],
            "depth": depth[ok], "press": press[ok],
            "sensors": np.asarray(m.ir_sensors_mm, np.float64)}


def calibrate(pad_name: str, sessions: Sequence[tuple[str, int]] = PROTOCOL_SESSIONS,
              xy_degree: int = 3, depth_degree: int = 2) -> tuple[SagCorrection, float]:
    """The correction fitted on the pad's ``sessions`` ((trajectory, seed) pairs) as
    ``fydpad calibrate indentation`` fits it (``SagCorrection.fit_cv``: the ridge by
    cross-validation over presses), and its held-out RMSE in mm."""
    parts = [indentation_samples(pad_name, t, s) for t, s in sessions]
    offset = 0
    for p in parts:  # presses of different sessions are different presses
        p["press"] = p["press"] + offset
        offset = int(p["press"].max(initial=offset)) + 1
    d = {k: np.concatenate([p[k] for p in parts]) for k in ("e", "x", "y", "depth", "press")}
    corr, held, _ = SagCorrection.fit_cv(d["e"], d["x"], d["y"], d["depth"], d["press"],
                                         xy_degree, depth_degree,
                                         sensors_mm=parts[0]["sensors"])
    return corr, held


def causal_indentation(pad_name: str, trajectory: str, seed: int, correction: SagCorrection,
                       seconds: float | None = None, fps: float = 30.0
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(estimate, true depth) in mm at the contact frames of a session with a usable
    estimate, through ``fydpad track``'s path: ``CausalIndentation`` fed frame by frame,
    the correction in the estimator, the rest distances from the samples before the
    first contact (the rule ``indentation_samples`` follows too). ``seconds``: by
    default ``session_seconds``."""
    seconds = session_seconds(trajectory) if seconds is None else seconds
    pad = SyntheticPad(SynthConfig(trajectory=trajectory, seconds=seconds, seed=seed,
                                   fps=fps, **TEST_PADS[pad_name]))
    t_ir, volts = pad.ir()
    m = pad.meta()
    est = IndentationEstimator(sensors_mm=m.ir_sensors_mm, base_to_fabric_mm=m.base_to_fabric_mm,
                               correction=correction)
    causal = CausalIndentation(est, t_ir, volts)
    got, want = [], []
    for k in range(pad.frame_count):
        q = pad.truth(k)
        depth = causal.at(q.t_s, q.x_mm, q.y_mm, q.contact)
        if q.contact and np.isfinite(depth):
            got.append(depth)
            want.append(q.indentation_mm)
    return np.array(got), np.array(want)
