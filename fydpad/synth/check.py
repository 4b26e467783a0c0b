"""Sanity figures of a synthetic recording against its own truth.

- the contact tracker (paper or robust) on every frame: RMSE, missed and false contacts
  (``vision.evaluation.score_tracking``), over all frames and over the *steady* frames:
  those not next to a change of the true contact. A frame's truth is the finger at the
  middle of its exposure, so a frame next to a touch or a release may have seen the
  contact for part of its exposure: either answer is defensible there;
- the paper's plane indentation (eq. 1 + eq. 2) at the true centroids, with the rest
  distances the reader estimates from the no-contact samples: RMSE against the true
  indentation over the contact frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from vision.contact import ContactTracker
from vision.evaluation import TrackingScore, score_tracking
from vision.indentation import IndentationEstimator, indentation_at_frames
from vision.recording import PadRecording


@dataclass(frozen=True)
class RecordingCheck:
    tracking: TrackingScore
    #: The same over the frames not next to a change of the true contact.
    steady: TrackingScore
    plane_rmse_mm: float
    max_indentation_mm: float


def steady_frames(contact: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Frames whose true contact equals both neighbours' (no touch or release within
    the exposure, which is shorter than the frame interval)."""
    c = np.asarray(contact, bool)
    same = np.ones(c.size, bool)
    same[1:] &= c[1:] == c[:-1]
    same[:-1] &= c[:-1] == c[1:]
    return same


def check_recording(recdir: str | Path, method: str = "paper") -> RecordingCheck:
    rec = PadRecording(recdir)
    m = rec.meta
    truth = rec.read_truth()
    if truth is None:
        raise ValueError(f"{recdir}: no truth.csv")
    tracker = ContactTracker(roi_px=m.roi_px, workspace_mm=m.workspace_mm,
                             image_flip=m.image_flip, method=method)
    n = truth.t_s.size
    c = np.zeros(n, bool)
    x = np.full(n, np.nan)
    y = np.full(n, np.nan)
    for k, _, frame in rec.frames():
        hit = tracker.process(frame)
        if hit is not None and k < n:
            c[k], x[k], y[k] = True, hit.x_mm, hit.y_mm
    score = score_tracking(c, x, y, truth.contact, truth.x_mm, truth.y_mm)
    s = steady_frames(truth.contact)
    steady = score_tracking(c[s], x[s], y[s], truth.contact[s], truth.x_mm[s], truth.y_mm[s])
    plane = float("nan")
    ir = rec.read_ir()
    if ir is not None and truth.contact.any():
        est = IndentationEstimator(sensors_mm=m.ir_sensors_mm,
                                   base_to_fabric_mm=m.base_to_fabric_mm)
        res, _ = indentation_at_frames(est, ir[0], ir[1], truth.t_s, truth.contact,
                                       np.where(truth.contact, truth.x_mm, np.nan),
                                       np.where(truth.contact, truth.y_mm, np.nan))
        tc = truth.contact
        err = res.indentation_mm[tc] - truth.indentation_mm[tc]
        plane = float(np.sqrt(np.nanmean(err ** 2)))
    return RecordingCheck(score, steady, plane, float(truth.indentation_mm.max()))
