"""From a pad session recording to the :class:`FingerState` stream, frame by frame.

Tracking, speed, indentation and force come together here, causally (each frame uses
only what was known at its time, as a live station would), so ``fydpad track``, the
tele-operation replay and the demo see the same stream the station produces.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from vision.config import IRConfig
from vision.contact import Contact, ContactTracker
from vision.indentation import (
    BASELINE_MARGIN_S,
    INVALID,
    DistanceFilterState,
    IndentationEstimator,
    filter_distances_mm,
)
from vision.recording import PadRecording
from vision.sources import Frame, VideoSource
from vision.speed import SpeedState, speed_update
from vision.state import FingerState


@dataclass
class TrackedFrame:
    frame: Frame
    contact: Contact | None
    state: FingerState


class FingerStateBuilder:
    """Contact, indentation and force of one frame into a :class:`FingerState`, with the
    speed differentiated from the centroid stream (paper III-B, 10 Hz low-pass)."""

    def __init__(self, cutoff_hz: float = 10.0):
        self.cutoff_hz = cutoff_hz
        self._speed = SpeedState()

    def build(
        self, t_s: float, contact: Contact | None, indentation_mm: float = math.nan,
        force_n: float = math.nan,
    ) -> FingerState:
        if contact is None:
            _, self._speed = speed_update(self._speed, t_s, math.nan, math.nan, False,
                                          self.cutoff_hz)
            # Without contact the indentation is 0 wherever it is measured at all.
            ind = 0.0 if math.isfinite(indentation_mm) else math.nan
            return FingerState(t_s, False, indentation_mm=ind, speed_mm_s=0.0, force_n=force_n)
        v, self._speed = speed_update(self._speed, t_s, contact.x_mm, contact.y_mm, True,
                                      self.cutoff_hz)
        return FingerState(t_s, True, contact.x_mm, contact.y_mm, indentation_mm, v, force_n)


class CausalIndentation:
    """Indentation at each frame of a recording from the IR samples up to that frame.

    The frame's share of the samples (those since the previous frame, none after it) goes
    to a :class:`LiveIndentation` that keeps every sample before the first contact for
    the rest distances, so a recording and a live station fed the same samples at the
    same frames give the same indentation: ``filter_distances_mm`` (a Kalman filter per
    sensor fed every new measurement up to the frame, each at its measurement time, the
    sensors' held outputs skipped, and predicted to the frame time); the
    rest distances the configured or ``meta.json`` ones, else estimated at the first
    contact from the samples taken before it (less a margin) and kept.
    """

    def __init__(self, estimator: IndentationEstimator, t_ir_s: np.ndarray, volts: np.ndarray):
        self.t_ir_s = t_ir_s
        self.volts = volts
        self._live = LiveIndentation(estimator, keep=None)
        self._next = 0  # first IR sample not yet given to the filter

    @property
    def estimator(self) -> IndentationEstimator:
        return self._live.estimator

    def at(self, t_s: float, x_mm: float, y_mm: float, contact: bool) -> float:
        end = max(int(np.searchsorted(self.t_ir_s, t_s, side="right")), self._next)
        k = slice(self._next, end)
        self._next = end
        return self._live.update_at(self.t_ir_s[k], self.volts[k], t_s, x_mm, y_mm, contact)


class LiveIndentation:
    """Indentation at each frame of a live station from every IR sample that arrived
    since the previous frame, filtered as :class:`CausalIndentation` does (the path of
    ``fydpad track``): ``filter_distances_mm``, a Kalman filter per sensor, state kept
    from frame to frame. Fed the same samples at the same frames, both give the same
    indentation.

    Without configured rest distances, the samples that arrived at frames without
    contact are kept (the newest ``keep``; ``None``: all); at the first contact, those
    taken more than ``BASELINE_MARGIN_S`` before it give the rest distances
    (``with_baseline_from``: the interquartile mean per sensor), kept for the rest of the
    session.
    """

    def __init__(self, estimator: IndentationEstimator, keep: int | None = 6000):
        self.estimator = estimator
        self._filter = DistanceFilterState.initial()
        self._keep = keep
        self._rest: deque[tuple[np.ndarray, np.ndarray]] = deque()  # (t_s[n], volts[n, 3])
        self._rest_n = 0

    def update(self, t_ir_s: np.ndarray, volts: np.ndarray, t_s: float,
               contact: Contact | None) -> float:
        """``t_ir_s``, ``volts[n, 3]``: the IR samples since the last call, oldest first
        (NaN where invalid); ``t_s``: the frame's time. Returns the indentation in mm
        (0 without contact; NaN without usable IR)."""
        if contact is None:
            return self.update_at(t_ir_s, volts, t_s, math.nan, math.nan, False)
        return self.update_at(t_ir_s, volts, t_s, contact.x_mm, contact.y_mm, True)

    def update_at(self, t_ir_s: np.ndarray, volts: np.ndarray, t_s: float, x_mm: float,
                  y_mm: float, contact: bool) -> float:
        """:meth:`update` with the contact as a flag and a centroid."""
        t_ir_s = np.asarray(t_ir_s, np.float64).reshape(-1)
        volts = np.asarray(volts, np.float64).reshape(-1, 3)
        d, fl = self.estimator.distances_mm(volts)
        # A live camera's clock starts at its first frame, after the station's: its frame
        # times can trail the sensors'. Never predict backwards past the newest sample.
        t_q = max(t_s, float(t_ir_s[-1])) if t_ir_s.size else t_s
        # The filter follows every sample, with or without contact, so it has settled
        # on the fabric when the finger lands.
        dist, flags, self._filter = filter_distances_mm(
            self._filter, t_ir_s, d, fl, t_q, sensor_period_s=self.estimator.sensor_period_s)
        if self.estimator.baseline_mm is None and t_ir_s.size:
            self._keep_rest(t_ir_s, volts)
        if not contact:
            return 0.0
        if self.estimator.baseline_mm is None:
            t_rest = np.concatenate([b[0] for b in self._rest]) if self._rest else np.empty(0)
            v_rest = (np.concatenate([b[1] for b in self._rest]) if self._rest
                      else np.empty((0, 3)))
            before = t_rest < t_s - BASELINE_MARGIN_S
            self.estimator = self.estimator.with_baseline_from(v_rest[before],
                                                               np.ones(int(before.sum()), bool))
            self._rest.clear()
            self._rest_n = 0
        if flags & int(INVALID):
            return math.nan
        return self.estimator.depth_at(float(dist[0]), float(dist[1]), float(dist[2]), x_mm,
                                       y_mm)

    def _keep_rest(self, t_ir_s: np.ndarray, volts: np.ndarray) -> None:
        """The newest ``keep`` samples, as whole batches (one per frame) where possible."""
        self._rest.append((t_ir_s, volts))
        self._rest_n += t_ir_s.size
        if self._keep is None:
            return
        while self._rest_n - self._rest[0][0].size >= self._keep:
            self._rest_n -= self._rest.popleft()[0].size
        extra = self._rest_n - self._keep
        if extra > 0:  # the oldest batch in part
            t0, v0 = self._rest[0]
            self._rest[0] = (t0[extra:], v0[extra:])
            self._rest_n -= extra


def recording_estimator(rec: PadRecording, ir_config: IRConfig | None = None
                        ) -> IndentationEstimator:
    """The indentation estimator for a recording: the device's polynomials, the
    recording's sensor positions and rest distances (meta.json) where it gives them."""
    m = rec.meta
    return IndentationEstimator.from_config(
        ir_config or IRConfig(), sensors_mm=m.ir_sensors_mm, baseline_mm=m.ir_baseline_mm,
        base_to_fabric_mm=m.base_to_fabric_mm,
    )


def finger_states(
    rec: PadRecording,
    tracker: ContactTracker,
    ir_config: IRConfig | None = None,
    source: Iterator[Frame] | None = None,
) -> Iterator[TrackedFrame]:
    """Track every frame of ``rec`` and yield its finger state.

    ``indentation_mm`` is NaN where the recording has no ``ir.csv``; ``force_n`` is the
    load cell's latest sample at the frame's time (NaN without ``force.csv``).
    """
    ir = rec.read_ir()
    indentation = (CausalIndentation(recording_estimator(rec, ir_config), *ir)
                   if ir is not None else None)
    force = rec.read_force()
    builder = FingerStateBuilder()
    frames = source if source is not None else VideoSource(rec).frames()
    for frame in frames:
        force_n = math.nan
        if force is not None:
            i = int(np.searchsorted(force[0], frame.t_s, side="right")) - 1
            force_n = float(force[1][i]) if i >= 0 else math.nan
        contact = tracker.process(frame.image)
        ind = math.nan
        if indentation is not None:
            ind = (indentation.at(frame.t_s, contact.x_mm, contact.y_mm, True)
                   if contact is not None else indentation.at(frame.t_s, math.nan, math.nan,
                                                              False))
        yield TrackedFrame(frame, contact, builder.build(frame.t_s, contact, ind, force_n))


def live_states(frames: Iterator[Frame], tracker: ContactTracker) -> Iterator[TrackedFrame]:
    """The finger states of a camera without sensors: position and speed only."""
    builder = FingerStateBuilder()
    for frame in frames:
        contact = tracker.process(frame.image)
        yield TrackedFrame(frame, contact, builder.build(frame.t_s, contact))
