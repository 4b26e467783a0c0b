"""The master station: each loop at its own rate, handing the others the latest value.

- vision (a thread, at the camera rate or the slower ``vision_hz``, dropping the frames
  in between): frame -> contact -> :class:`FingerState`, published to the render
  process, the tele-operation link and the recorder;
- sensors (a thread, at the sensor rate): IR voltages and load-cell force, latest value,
  replayed (:class:`SensorFeed`) or from the serial board (:class:`SerialSensorFeed`);
  every IR sample also goes through a bounded ring (:class:`IRBuffer`) to the vision
  loop, which filters those since its last frame into the indentation;
- render (a process, 1 kHz): see :mod:`fydpad.station.render`;
- tele-operation (a thread, at the vision rate): the latest state to the slave.

A fault in any loop, Ctrl-C or the end of ``duration_s`` stops everything the same
way: vibration off and motors to rest (the render process), the robot told to hold
(the link), files flushed and closed.

The operator hold (:meth:`Station.set_operator_hold`, from the terminal's key, the web
view's button or the sensor board's pedal): the robot holds still (the link's samples
carry the flag), the vibration goes silent, the softness stays (the finger keeps its
support); released, the robot glides back to the finger. Every change is an event of the
recording (``events.csv``).
"""

from __future__ import annotations

import math
import multiprocessing as mp
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fydpad.pacing import LoopTimer
from fydpad.softness import LiveStiffness
from fydpad.station.ir_buffer import IRBuffer
from fydpad.station.render import CONTROL_FIELDS, RenderSpec, render_main
from fydpad.station.shared import SharedFingerState, SharedRecord
from fydpad.station.snapshot import Snapshot, View
from vision.contact import ContactTracker
from vision.errors import DeviceFault
from vision.recording import CsvRowWriter, PadMeta, PadRecordingWriter, TrackWriter, write_meta
from vision.sources import FrameSource
from vision.state import FingerState
from vision.stream import FingerStateBuilder, LiveIndentation


class StationFault(DeviceFault, RuntimeError):
    """A loop of the station failed; the station has stopped safely."""

    device = "station"
    check = "the loop and device the message names (vibration is off, the motors at rest)"


@dataclass
class LatestSensors:
    """The newest IR voltages and force, written by the sensor loop; while the station
    records, every sample also goes to ``sink`` (``write_ir``/``write_force``), so the
    recording keeps the sensor rate, not the vision rate; with ``ir_buffer``, every IR
    sample also goes to it, for the vision loop to filter them all."""

    t_s: float = math.nan
    volts: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    force_n: float = math.nan
    sink: Any = None
    ir_buffer: IRBuffer | None = None

    def set_ir(self, t_s: float, volts: tuple[float, float, float],
               recorded: tuple[float, float, float] | None = None) -> None:
        """``volts`` for the station (NaN where invalid); ``recorded``: as read, if other."""
        self.volts = volts
        self.t_s = t_s
        buf = self.ir_buffer
        if buf is not None:
            buf.push(t_s, volts)
        sink = self.sink
        if sink is not None and t_s >= 0:
            sink.write_ir(t_s, *(volts if recorded is None else recorded))

    def set_force(self, t_s: float, force_n: float) -> None:
        self.force_n = force_n
        sink = self.sink
        if sink is not None and t_s >= 0:
            sink.write_force(t_s, force_n)


class SensorFeed:
    """Sensor samples replayed at their own time stamps (``ir.csv``/``force.csv``).

    In real time, :meth:`run` sleeps until each sample is due on the station's clock; on
    a stop it still applies those that fell due before it (a late thread on a loaded
    machine loses none, as a serial port's buffer would keep them). As fast as possible
    (``--as-fast-as-possible``) the frames' own times are the clock: the vision loop calls
    :meth:`advance_to` with each frame's time (dropped frames too), and at the end of the
    source :meth:`finish`, so every frame sees the samples up to it however fast or slow
    the machine is, and a recording keeps every sample.
    """

    def __init__(self, ir=None, force=None):
        self.ir = ir
        self.force = force
        # Both streams merged in time order: (t_s, 0 = IR | 1 = force, row).
        events = []
        if ir is not None:
            events += [(float(t), 0, i) for i, t in enumerate(ir[0])]
        if force is not None:
            events += [(float(t), 1, i) for i, t in enumerate(force[0])]
        events.sort()
        self._events = events
        self._next = 0

    def _apply(self, event: tuple[float, int, int], latest: LatestSensors) -> None:
        t_s, kind, i = event
        if kind == 0:
            v = self.ir[1][i]
            latest.set_ir(t_s, (float(v[0]), float(v[1]), float(v[2])))
        else:
            latest.set_force(t_s, float(self.force[1][i]))

    def advance_to(self, t_s: float, latest: LatestSensors) -> None:
        """Apply every sample due at or before ``t_s`` (session seconds)."""
        events = self._events
        while self._next < len(events) and events[self._next][0] <= t_s:
            self._apply(events[self._next], latest)
            self._next += 1

    def finish(self, latest: LatestSensors) -> None:
        """Apply every sample left (the source has ended)."""
        self.advance_to(math.inf, latest)

    def run(self, latest: LatestSensors, clock_t0: float, stop: threading.Event) -> None:
        events = self._events
        while self._next < len(events):
            if stop.is_set():
                # Those due before the stop was seen arrived before it: keep them.
                self.advance_to(time.perf_counter() - clock_t0, latest)
                return
            event = events[self._next]
            delay = clock_t0 + event[0] - time.perf_counter()
            if delay > 0:
                stop.wait(delay)
                continue  # stopped meanwhile, or due now
            self._apply(event, latest)
            self._next += 1


class ClockOffset:
    """A device clock onto the host's: host time = device time + offset, the offset being
    the smallest (arrival - device time) over the last ``window_s`` of device time, i.e.
    the least delayed line's (USB delivers lines late and in bursts). A window, not the
    whole session: a device clock that runs fast or slow against the host's drifts the
    offset, and the session-long minimum would hold an early value for good (a 1 s
    window errs by the drift over 1 s: 2 ms at 0.2 %, an RC-clocked microcontroller's
    worst; 100 lines a second still hold a barely delayed one). Mapped times never go
    backwards. Amortised O(1) per sample (a monotonic queue)."""

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = float(window_s)
        self._q: deque[tuple[float, float]] = deque()  # (device t, delay), delays rising
        self._last = -math.inf

    def map(self, device_t_s: float, arrival_s: float) -> float:
        delay = arrival_s - device_t_s
        q = self._q
        while q and q[-1][1] >= delay:
            q.pop()
        q.append((device_t_s, delay))
        while q[0][0] < device_t_s - self.window_s:
            q.popleft()
        self._last = max(self._last, device_t_s + q[0][1])
        return self._last


class SerialSensorFeed:
    """The serial IR + load-cell board (docs/sensor_board_protocol.md), live.

    Reads every line at the board's rate and keeps the newest values; garbage, partial
    lines and bad checksums are dropped and counted by the reader. A board that sends
    nothing valid for ``board.timeout_s`` raises :class:`vision.sensors.SensorError`
    naming the port, which stops the station safely.
    """

    def __init__(self, board):
        self.board = board
        #: Called with the deadman pedal's state (True pressed) on each change, and once
        #: with the first state read; unset: the pedal is not used.
        self.on_pedal: Callable[[bool], None] | None = None
        self.samples = 0
        self.invalid_ir = 0
        self.saturated_force = 0

    def run(self, latest: LatestSensors, clock_t0: float, stop: threading.Event) -> None:
        # Lines queued before the station started are stale: start from the newest.
        self.board.flush_input()
        clock = ClockOffset()  # the board's clock onto the station's
        last_pedal: bool | None = None
        try:
            while not stop.is_set():
                ir, force = self.board.read()
                t_s = clock.map(ir.t_s, time.perf_counter() - clock_t0)
                # An out-of-range voltage is no distance: NaN, so no indentation is made up.
                latest.set_ir(t_s, tuple(v if ok else math.nan
                                         for v, ok in zip(ir.volts, ir.valid, strict=True)),
                              recorded=ir.volts)
                self.invalid_ir += not all(ir.valid)
                if force is not None:
                    latest.set_force(t_s, force.force_n)
                    self.saturated_force += force.saturated
                self.samples += 1
                pedal = self.board.pedal
                if pedal is not None and pedal != last_pedal:
                    last_pedal = pedal
                    if self.on_pedal is not None:
                        self.on_pedal(pedal)
        finally:
            self.board.close()

    def close(self) -> None:
        self.board.close()

    def status(self) -> dict:
        st = self.board.stats
        return {"port": self.board.port, "samples": self.samples, "pedal": self.board.pedal,
                "bad_lines": st.bad_checksum + st.malformed + st.overlong,
                "invalid_ir": self.invalid_ir, "saturated_force": self.saturated_force,
                "board_resets": st.board_resets}


class _NoVideoWriter:
    """A recording without its video (``--no-video``): meta.json, ir.csv and force.csv
    as :class:`PadRecordingWriter` writes them, frames not kept."""

    def __init__(self, recdir: Path, meta: PadMeta):
        recdir.mkdir(parents=True, exist_ok=True)
        write_meta(recdir, meta)
        self._ir = CsvRowWriter(recdir / "ir.csv", ("t_s", "v0", "v1", "v2"))
        self._force = CsvRowWriter(recdir / "force.csv", ("t_s", "force_n"))

    def write_frame(self, frame_bgr) -> None:
        pass

    def write_ir(self, t_s: float, v0: float, v1: float, v2: float) -> None:
        self._ir.write(t_s, v0, v1, v2)

    def write_force(self, t_s: float, force_n: float) -> None:
        self._force.write(t_s, force_n)

    def close(self) -> None:
        self._ir.close()
        self._force.close()


@dataclass
class StationOptions:
    duration_s: float | None = None
    #: Pace a recorded source at its own frame times (False: as fast as it decodes).
    real_time: bool = True
    #: Track at this rate (the paper: 10 Hz), dropping the frames in between; None: every
    #: frame (the camera rate). Tele-operation follows at the same rate.
    vision_hz: float | None = None
    record_dir: str | None = None
    record_video: bool = True
    render: RenderSpec = field(default_factory=RenderSpec)
    #: Called with the latest state at the vision rate (the tele-operation link).
    teleop_send: Callable[[FingerState], None] | None = None
    teleop_hold: Callable[[], None] | None = None
    #: Called with the operator hold on each change (the link's ``set_operator_hold``).
    operator_hold: Callable[[bool], None] | None = None
    status: Callable[[dict], None] | None = None
    #: How long the render process may take to start and build its chain (a board to
    #: connect): a bound against a hang; a loaded 2-core machine has taken over 30 s.
    render_start_timeout_s: float = 120.0


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
        ir_buffer: IRBuffer | None = None,
    ):
        self.source = source
        self.tracker = tracker
        self.meta = meta
        self.options = options
        self.sensors = sensors
        self.indentation = indentation
        self.latest = LatestSensors()
        if indentation is not None:  # every IR sample, for the indentation's filter
            self.latest.ir_buffer = ir_buffer or IRBuffer()
        self.shared = SharedFingerState()
        self.control = SharedRecord(CONTROL_FIELDS)
        self._control = [options.render.vibration_gain, options.render.stiffness_n_per_mm, 1.0,
                         math.nan, 0.0, math.nan, 0.0]  # texture 0, b of the file, no hold
        self._control_lock = threading.Lock()
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
        self._writer: PadRecordingWriter | _NoVideoWriter | None = None
        self._track: TrackWriter | None = None
        #: The station clock's zero (perf_counter seconds), set when the loops start.
        self.t0: float | None = None
        self.frames_dropped = 0
        #: A replayed feed as fast as possible: advanced by the vision loop, no thread.
        self._sensors_by_frame = (not options.real_time
                                  and hasattr(self.sensors, "advance_to"))
        #: The operator hold (``set_operator_hold``) and its changes: (t_s, on, source).
        self.operator_hold = False
        self.hold_events: list[tuple[float, bool, str]] = []
        self._hold_lock = threading.Lock()
        self._deadman_released = False
        self._events: CsvRowWriter | None = None
        if isinstance(sensors, SerialSensorFeed):  # a deadman pedal: released holds
            sensors.on_pedal = lambda pressed: self.set_operator_hold(not pressed, "pedal")

    # -- operator hold -----------------------------------------------------------

    def set_operator_hold(self, on: bool, source: str = "api") -> bool:
        """Hold (True) or release (False), from any input (``source``: "key", "web",
        "pedal", ...); returns the hold as it is now. Held: the link's samples carry the
        flag (the robot holds still), the vibration is silenced (the render process's
        ``operator_hold`` control), the softness stays. Each change is recorded."""
        on = bool(on)
        with self._hold_lock:
            if source == "pedal":
                self._deadman_released = on
            elif not on and self._deadman_released:
                return self.operator_hold  # the deadman pedal is released: it holds
            if on == self.operator_hold:
                return on
            self.operator_hold = on
            t_s = time.perf_counter() - self.t0 if self.t0 is not None else 0.0
            self.hold_events.append((t_s, on, source))
            self.set_control(operator_hold=1.0 if on else 0.0)
            if self.options.operator_hold is not None:
                try:
                    self.options.operator_hold(on)
                except Exception as exc:  # a link fault is the link's: never this input's
                    self.faults.append(f"operator hold on the link: {exc}")
                    self.stop_event.set()
            if self._events is not None:  # rare: each one on disk at once
                self._events.write(t_s, "hold" if on else "release", source)
                self._events.flush()
        return on

    def toggle_operator_hold(self, source: str = "api") -> bool:
        with self._hold_lock:
            on = not self.operator_hold
        return self.set_operator_hold(on, source)

    # -- control ----------------------------------------------------------------

    def set_control(self, **values: float) -> None:
        """Change some of the render process's control fields (``CONTROL_FIELDS``, by name),
        keep the others. The control record's one writer: the web view's changes and the
        station's epoch all come here, under a lock, so none is lost and the seqlock never
        has two writers."""
        unknown = set(values) - set(CONTROL_FIELDS)
        if unknown:
            raise KeyError(f"unknown control field {sorted(unknown)[0]!r} "
                           f"(known: {', '.join(CONTROL_FIELDS)})")
        with self._control_lock:
            for name, v in values.items():
                self._control[CONTROL_FIELDS.index(name)] = float(v)
            self.control.write(self._control)

    def control_values(self) -> dict[str, float]:
        """The control fields as last set (by name)."""
        with self._control_lock:
            return dict(zip(CONTROL_FIELDS, self._control, strict=True))

    # -- loops ------------------------------------------------------------------

    def _camera_dropped(self) -> dict:
        """A live camera's failed reads (dropped frames, counted, not fatal) and outages."""
        failures = getattr(self.source, "read_failures", None)
        if failures is None:
            return {}
        return {"camera_read_failures": failures,
                "camera_outages": len(self.source.dropouts) + self.source.dropouts_unlisted}

    def _vision_rate_hz(self) -> float:
        hz = self.options.vision_hz
        return self.source.fps if hz is None else min(float(hz), self.source.fps)

    def _vision_loop(self, t0: float) -> None:
        rate_hz = self._vision_rate_hz()
        timer = LoopTimer(rate_hz, "vision", on_time_s=0.5 / rate_hz)
        writer, track = self._writer, self._track
        opts = self.options
        # Frames are due every 1/rate_hz of their own time stamps; those in between are
        # read and dropped (never queued), so tracking always sees the newest frame.
        period_s = 1.0 / rate_hz
        slack_s = 0.5 / self.source.fps
        due_s = -math.inf
        by_frame = self.sensors if self._sensors_by_frame else None
        try:
            builder = FingerStateBuilder()
            timer.start(at=t0)
            for frame in self.source.frames():
                if self.stop_event.is_set():
                    break
                if by_frame is not None:  # every frame read, dropped ones too
                    by_frame.advance_to(frame.t_s, self.latest)
                if frame.t_s < due_s - slack_s:
                    self.frames_dropped += 1
                    if writer is not None:  # the video keeps every frame: it replays as shot
                        writer.write_frame(frame.image)
                    continue
                # After a gap (a stalled camera) pace from this frame, without a burst.
                due_s = max(due_s + period_s, frame.t_s + period_s)
                if opts.real_time:
                    arrival = timer.wait_until(t0 + frame.t_s)
                else:
                    arrival = timer.mark()
                contact = self.tracker.process(frame.image)
                s = self.latest
                ind = math.nan
                if self.indentation is not None:  # the IR samples since the last frame
                    t_ir, volts = s.ir_buffer.drain()
                    ind = self.indentation.update(t_ir, volts, frame.t_s, contact)
                state = builder.build(frame.t_s, contact, ind, s.force_n)
                # The stiffness the finger actually feels: F / delta over each press; a
                # saturated load cell (at full scale) no longer measures the force.
                if not abs(state.force_n) >= self.force_full_scale_n:
                    self.stiffness.update(state.force_n, state.indentation_mm)
                self.contact_frames += state.contact
                self.shared.publish(state, arrival, frame.index)
                self.snapshot.publish(View(frame.index, frame.image, contact, state))
                if timer.stats_due():
                    self.live_stats["vision"] = {**timer.stats().as_dict(),
                                                 **self._camera_dropped()}
                self.last_state = state
                self.frames += 1
                if opts.teleop_send is not None:
                    opts.teleop_send(state)
                if writer is not None:
                    writer.write_frame(frame.image)
                if track is not None:
                    track.write_row(frame.t_s, frame.index, state.contact, state.x_mm,
                                    state.y_mm, state.indentation_mm)
                # In real time the station's clock, else the session's (the frames').
                elapsed_s = time.perf_counter() - t0 if opts.real_time else frame.t_s
                if opts.duration_s is not None and elapsed_s >= opts.duration_s:
                    break
            else:
                if by_frame is not None and not self.stop_event.is_set():
                    by_frame.finish(self.latest)  # the source ended: the samples after it
        except Exception as exc:
            self.faults.append(f"vision loop: {exc}")
        finally:
            self.stats["vision"] = {**timer.stats().as_dict(),
                                    "frames_dropped": self.frames_dropped,
                                    **self._camera_dropped()}
            if self.latest.ir_buffer is not None:
                # lost > 0: the vision loop fell behind by more than the ring holds.
                self.stats["vision"]["ir_samples"] = self.latest.ir_buffer.stats()
            self.stop_event.set()

    def _sensor_loop(self, t0: float) -> None:
        try:
            self.sensors.run(self.latest, t0, self.stop_event)
        except Exception as exc:
            self.faults.append(f"sensor loop: {exc}")
            self.stop_event.set()

    # -- recording --------------------------------------------------------------

    def _open_recording(self) -> None:
        """The session's files, opened before the vision and sensor loops start and
        closed after every loop has stopped (both loops write to them)."""
        if not self.options.record_dir:
            return
        rec = Path(self.options.record_dir)
        meta = PadMeta(**{**self.meta.__dict__, "fps": self.source.fps,
                          "frame_size": self.source.frame_size})
        self._writer = (PadRecordingWriter(rec, meta) if self.options.record_video
                        else _NoVideoWriter(rec, meta))
        self._track = TrackWriter(rec / "track.csv")
        self.latest.sink = self._writer
        with self._hold_lock:
            self._events = CsvRowWriter(rec / "events.csv", ("t_s", "event", "detail"))
            for t_s, on, source in self.hold_events:  # those before the recording opened
                self._events.write(t_s, "hold" if on else "release", source)

    def _close_recording(self) -> None:
        self.latest.sink = None
        with self._hold_lock:
            events, self._events = self._events, None
        if events is not None:
            # What the render process's rings lost to a disk stalled past them: counted
            # in the recording itself, never silently.
            t_end = time.perf_counter() - self.t0 if self.t0 is not None else 0.0
            render = self.stats.get("render", {})
            lost = render.get("commands_log", {}).get("dropped", 0)
            if lost:
                events.write(t_end, "lost_rows", f"commands.csv: {lost} rows")
            # A live camera's outages, on the frames' clock (frames.csv's t_s).
            for t_s, index, failed, gap_s in getattr(self.source, "dropouts", ()):
                events.write(t_s, "camera_dropout", f"{self.source}: {failed} failed reads "
                             f"over {gap_s:.3f} s after frame {index}")
            channels = (render.get("chain") or {}).get("channels") or {}
            for name, st in channels.items():
                if st.get("dropped_samples"):
                    events.write(t_end, "lost_samples",
                                 f"{name}: {st['dropped_samples']} samples")
            events.close()
        for w in (self._writer, self._track):
            if w is not None:
                w.close()

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
                if hasattr(self.sensors, "close"):
                    self.sensors.close()
                raise StationFault("; ".join(f.splitlines()[0] for f in self.faults)
                                   or "render process did not start")
        t0 = time.perf_counter() + 0.05
        self.t0 = t0
        # Only the epoch: the web view may have set other fields while the chain was built.
        self.set_control(epoch_s=t0)
        threads = [threading.Thread(target=self._vision_loop, args=(t0,), name="vision")]
        if self.sensors is not None and not self._sensors_by_frame:
            threads.append(threading.Thread(target=self._sensor_loop, args=(t0,),
                                            name="sensors", daemon=True))
        try:
            self._open_recording()
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
                if th.ident is not None:  # not started if the recording could not open
                    th.join(timeout=5)
            render_stop.set()
            render.join(timeout=5)
            if render.is_alive():
                render.kill()
                self.faults.append("render process did not stop in 5 s: killed")
            self._drain(results, final=True)
            self.source.close()
            if hasattr(self.sensors, "close"):
                self.sensors.close()
            self._close_recording()
        if isinstance(self.sensors, SerialSensorFeed):
            self.stats["sensors"] = self.sensors.status()
        self.stats["operator_hold"] = {"changes": len(self.hold_events),
                                       "held_at_stop": self.operator_hold}
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
            "vision": self.live_stats.get("vision"),
            "link": self.live_stats.get("link"),
            "operator_hold": self.operator_hold,
            "sensors": (self.sensors.status() if isinstance(self.sensors, SerialSensorFeed)
                        else None),
        }
