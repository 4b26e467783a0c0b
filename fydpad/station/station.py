"""The master station: each loop at its own rate, handing the others the latest value.

- vision (a thread, at the camera rate): frame -> contact -> :class:`FingerState`,
  published to the render process, the tele-operation link and the recorder;
- sensors (a thread, at the sensor rate): IR voltages and load-cell force, latest value;
- render (a process, 1 kHz): see :mod:`fydpad.station.render`;
- tele-operation (a thread, at the vision rate): the latest state to the slave.

A fault in any loop, Ctrl-C or the end of ``duration_s`` stops everything the same
way: vibration off and motors to rest (the render process), the robot told to hold
(the link), files flushed and closed.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fydpad.pacing import LoopTimer
from fydpad.softness import LiveStiffness
from fydpad.station.render import CONTROL_FIELDS, RenderSpec, render_main
from fydpad.station.shared import SharedFingerState, SharedRecord
from fydpad.station.snapshot import Snapshot, View
from vision.contact import ContactTracker
from vision.recording import PadMeta, PadRecordingWriter, TrackWriter
from vision.sources import FrameSource
from vision.state import FingerState
from vision.stream import FingerStateBuilder, LiveIndentation


class StationFault(RuntimeError):
    """A loop of the station failed; the station has stopped safely."""


@dataclass
class LatestSensors:
    """The newest IR voltages and force, written by the sensor loop."""

    t_s: float = math.nan
    volts: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    force_n: float = math.nan


class SensorFeed:
    """Sensor samples replayed at their own time stamps (``ir.csv``/``force.csv``)."""

    def __init__(self, ir=None, force=None):
        self.ir = ir
        self.force = force

    def run(self, latest: LatestSensors, clock_t0: float, stop: threading.Event) -> None:
        # Merge both streams in time order and sleep until each sample is due.
        events = []
        if self.ir is not None:
            t, v = self.ir
            events += [(float(t[i]), 0, i) for i in range(len(t))]
        if self.force is not None:
            t, _f = self.force
            events += [(float(t[i]), 1, i) for i in range(len(t))]
        events.sort()
        for t_s, kind, i in events:
            if stop.is_set():
                return
            delay = clock_t0 + t_s - time.perf_counter()
            if delay > 0:
                stop.wait(delay)
            if kind == 0:
                v = self.ir[1][i]
                latest.volts = (float(v[0]), float(v[1]), float(v[2]))
                latest.t_s = t_s
            else:
                latest.force_n = float(self.force[1][i])


@dataclass
class StationOptions:
    duration_s: float | None = None
    #: Pace a recorded source at its own frame times (False: as fast as it decodes).
    real_time: bool = True
    record_dir: str | None = None
    record_video: bool = True
    render: RenderSpec = field(default_factory=RenderSpec)
    #: Called with the latest state at the vision rate (the tele-operation link).
    teleop_send: Callable[[FingerState], None] | None = None
    teleop_hold: Callable[[], None] | None = None
    status: Callable[[dict], None] | None = None
    #: How long the render process may take to build its chain (a board to connect).
    render_start_timeout_s: float = 30.0


class Station:
    """Runs the loops until the source ends, ``duration_s`` passes, Ctrl-C, or a fault."""

    def __init__(
        self,
        source: FrameSource,
        tracker: ContactTracker,
        meta: PadMeta,
        options: StationOptions,
        sensors: SensorFeed | None = None,
        indentation: LiveIndentation | None = None,
        force_full_scale_n: float = math.inf,
    ):
        self.source = source
        self.tracker = tracker
        self.meta = meta
        self.options = options
        self.sensors = sensors
        self.indentation = indentation
        self.latest = LatestSensors()
        self.shared = SharedFingerState()
        self.control = SharedRecord(CONTROL_FIELDS)
        self._control = [options.render.vibration_gain, options.render.stiffness_n_per_mm, 1.0,
                         math.nan]
        self.control.write(self._control)
        self.stop_event = threading.Event()
        self.faults: list[str] = []
        self.stats: dict = {}
        #: Figures updated while running (the render process posts them once a second).
        self.live_stats: dict = {}
        self.frames = 0
        self.contact_frames = 0
        self.last_state: FingerState | None = None
        self.stiffness = LiveStiffness()
        self.force_full_scale_n = force_full_scale_n
        #: The latest frame, contact and state, for the web view and the status line.
        self.snapshot = Snapshot()

    # -- loops ------------------------------------------------------------------

    def _vision_loop(self, t0: float) -> None:
        timer = LoopTimer(self.source.fps, "vision", on_time_s=0.5 / self.source.fps)
        writer = track = None
        opts = self.options
        try:
            if opts.record_dir:
                rec = Path(opts.record_dir)
                meta = PadMeta(**{**self.meta.__dict__, "fps": self.source.fps,
                                  "frame_size": self.source.frame_size})
                writer = PadRecordingWriter(rec, meta) if opts.record_video else None
                track = TrackWriter(rec / "track.csv")
            builder = FingerStateBuilder()
            timer.start(at=t0)
            for frame in self.source.frames():
                if self.stop_event.is_set():
                    break
                if opts.real_time:
                    arrival = timer.wait_until(t0 + frame.t_s)
                else:
                    arrival = timer.mark()
                contact = self.tracker.process(frame.image)
                s = self.latest
                ind = (self.indentation.update(s.volts, contact)
                       if self.indentation is not None else math.nan)
                state = builder.build(frame.t_s, contact, ind, s.force_n)
                # The stiffness the finger actually feels: F / delta over each press; a
                # saturated load cell (at full scale) no longer measures the force.
                if not abs(state.force_n) >= self.force_full_scale_n:
                    self.stiffness.update(state.force_n, state.indentation_mm)
                self.contact_frames += state.contact
                self.shared.publish(state, arrival, frame.index)
                self.snapshot.publish(View(frame.index, frame.image, contact, state))
                if timer.stats_due():
                    self.live_stats["vision"] = timer.stats().as_dict()
                self.last_state = state
                self.frames += 1
                if opts.teleop_send is not None:
                    opts.teleop_send(state)
                if writer is not None:
                    writer.write_frame(frame.image)
                    if np.isfinite(s.t_s):
                        writer.write_ir(frame.t_s, *s.volts)
                    if np.isfinite(s.force_n):
                        writer.write_force(frame.t_s, s.force_n)
                if track is not None:
                    track.write_row(frame.t_s, frame.index, state.contact, state.x_mm,
                                    state.y_mm, state.indentation_mm)
                if opts.duration_s is not None and time.perf_counter() - t0 >= opts.duration_s:
                    break
        except Exception as exc:
            self.faults.append(f"vision loop: {exc}")
        finally:
            self.stats["vision"] = timer.stats().as_dict()
            if writer is not None:
                writer.close()
            if track is not None:
                track.close()
            self.stop_event.set()

    def _sensor_loop(self, t0: float) -> None:
        try:
            self.sensors.run(self.latest, t0, self.stop_event)
        except Exception as exc:
            self.faults.append(f"sensor loop: {exc}")
            self.stop_event.set()

    # -- run --------------------------------------------------------------------

    def run(self) -> dict:
        """Run to the end; returns the statistics. Raises StationFault after a fault."""
        ctx = mp.get_context("spawn")
        render_stop = ctx.Event()
        render_ready = ctx.Event()
        results = ctx.Queue()
        render = ctx.Process(
            target=render_main,
            args=(self.options.render, self.shared, self.control, render_stop, results,
                  render_ready),
            name="fydpad-render", daemon=True,
        )
        render.start()
        # No frame before the actuators are ready: wait for the render process's chain.
        deadline = time.monotonic() + self.options.render_start_timeout_s
        while not render_ready.wait(0.05):
            self._drain(results)
            if self.faults or not render.is_alive() or time.monotonic() > deadline:
                render_stop.set()
                render.join(timeout=5)
                self._drain(results, final=True)
                self.source.close()
                raise StationFault("; ".join(f.splitlines()[0] for f in self.faults)
                                   or "render process did not start")
        t0 = time.perf_counter() + 0.05
        self._control[3] = t0
        self.control.write(self._control)
        threads = [threading.Thread(target=self._vision_loop, args=(t0,), name="vision")]
        if self.sensors is not None:
            threads.append(threading.Thread(target=self._sensor_loop, args=(t0,),
                                            name="sensors", daemon=True))
        try:
            for th in threads:
                th.start()
            while not self.stop_event.wait(0.05):
                if not render.is_alive():
                    self.faults.append("render process died")
                    break
                self._drain(results)
                if self.options.status is not None:
                    self.options.status(self.status())
        finally:
            self.stop_event.set()
            if self.options.teleop_hold is not None:
                try:
                    self.options.teleop_hold()
                except Exception as exc:
                    self.faults.append(f"teleop hold: {exc}")
            for th in threads:
                th.join(timeout=5)
            render_stop.set()
            render.join(timeout=5)
            if render.is_alive():
                render.kill()
                self.faults.append("render process did not stop in 5 s: killed")
            self._drain(results, final=True)
            self.source.close()
        self.stats["softness"] = {
            "requested_n_per_mm": self.options.render.stiffness_n_per_mm,
            "measured_n_per_mm": self._measured_stiffness(),
            "presses": self.stiffness.presses,
        }
        if self.faults:
            raise StationFault("; ".join(f.splitlines()[0] for f in self.faults))
        return self.stats

    def _drain(self, results, final: bool = False) -> None:
        deadline = time.monotonic() + (2.0 if final else 0.0)
        while True:
            try:
                kind, payload = results.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                return
            if kind == "live":
                self.live_stats.update(payload)
            elif kind == "fault":
                self.faults.append(payload)
                self.stop_event.set()
            elif kind == "stats":
                self.stats.update(payload)
                if final:
                    return

    def _measured_stiffness(self) -> float:
        """The current press's F / delta, else the last finished press's."""
        k = self.stiffness.k_n_per_mm
        return k if math.isfinite(k) else self.stiffness.last_k_n_per_mm

    def status(self) -> dict:
        s = self.last_state
        return {
            "frames": self.frames,
            "contact": bool(s.contact) if s else False,
            "x_mm": s.x_mm if s else math.nan,
            "y_mm": s.y_mm if s else math.nan,
            "indentation_mm": s.indentation_mm if s else math.nan,
            "force_n": s.force_n if s else math.nan,
            "requested_n_per_mm": self.options.render.stiffness_n_per_mm,
            "measured_n_per_mm": self._measured_stiffness(),
            "render": self.live_stats.get("render"),
        }
