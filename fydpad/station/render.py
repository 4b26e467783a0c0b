"""The 1 kHz render loop, in a process of its own.

Measured on the 2-core station machine with the robust tracker running at 30 fps in
the main process (``python benchmarks/bench_render_loop.py``): a render *thread* under
the GIL kept about 99.2 % of its ticks on time with tens of skipped ticks in 5 s, short
of the 99.5 % target; a render *process* kept 99.8 % (99.96 % with SCHED_FIFO and its
own core). So the render loop runs here, in a process, reading the latest finger state
from shared memory and never waiting on anything.

Each tick: read the newest finger state (seqlock, no wait) -> the render chain (texture
vibration, softness position, eq. 3 PWM) -> the actuator. On a stop request, a fault
or any exception: vibration off, motors to rest (``RenderChain.safe_stop``).

No disk I/O in the loop: the commands log's rows go into a preallocated ring that a
thread writes (:class:`fydpad.station.row_log.RingRowLog`), as file channels' blocks do
(:class:`fydpad.station.outputs.FileWriter`); a disk that stalls past the ring's 2.5 s
drops rows, counted in the stats (``commands_log.dropped``), never a tick.
"""

from __future__ import annotations

import importlib
import multiprocessing as mp
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Protocol

from fydpad.errors import one_line_warnings
from fydpad.pacing import LatencyHistogram, LoopTimer
from fydpad.station.chains import build_render_chain
from fydpad.station.row_log import RingRowLog
from fydpad.station.shared import SharedFingerState, SharedRecord
from fydpad.station.spec import RenderSpec
from teleop.realtime import request_realtime

#: Control values the station may change while the render process runs. ``texture_index``
#: selects the texture model among ``[RenderSpec.texture, *RenderSpec.textures]`` (-1: none;
#: the experiment's stimuli); ``friction_b_v`` sets a friction model's b (NaN: the file's);
#: ``operator_hold`` (1: held) silences the vibration whatever ``vibration_enabled`` says.
CONTROL_FIELDS = ("vibration_gain", "stiffness_n_per_mm", "vibration_enabled", "epoch_s",
                  "texture_index", "friction_b_v", "operator_hold")


class RenderChain(Protocol):
    """What the render process drives once per tick."""

    #: Names of the values ``tick`` returns, for the commands log.
    outputs: tuple[str, ...]

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float, speed_mm_s: float,
             force_n: float, vibration_gain: float, stiffness_n_per_mm: float) -> tuple:
        """One 1 kHz step; returns the commanded values named by ``outputs``."""

    def safe_stop(self) -> None:
        """Vibration off, motors to rest. Must not raise."""


class NullChain:
    """No actuator: renders nothing, records the ticks (for sensing-only sessions)."""

    outputs = ("vibration", "position")

    def tick(self, t_s, contact, x_mm, y_mm, speed_mm_s, force_n, vibration_gain,
             stiffness_n_per_mm):
        return (0.0, 0.0)

    def safe_stop(self) -> None:
        pass


def build_chain(spec: RenderSpec) -> RenderChain:
    """The render chain for ``spec``; backends are imported here, inside the process."""
    if spec.chain is not None:
        module, _, name = spec.chain.partition(":")
        return getattr(importlib.import_module(module), name)(spec)
    if spec.motors == "none" and spec.texture is None and not spec.textures:
        return NullChain()
    return build_render_chain(spec)


def render_main(
    spec: RenderSpec,
    state: SharedFingerState,
    control: SharedRecord,
    stop_event,
    results,
    ready_event=None,
) -> None:
    """Entry point of the render process; posts ("stats", dict) and maybe ("fault", text)."""
    one_line_warnings("fydpad run")  # this process's warnings (a clamped speed) as one line
    # The writer threads (commands log, file channels) format under the GIL: a tick that
    # wants it back waits at most this long, not CPython's default 5 ms.
    sys.setswitchinterval(1e-4)
    scheduling = request_realtime(50, cpu=-1) if spec.realtime else "normal"
    timer = LoopTimer(spec.rate_hz, "render")
    latency = LatencyHistogram()
    chain: RenderChain | None = None
    log: RingRowLog | None = None
    try:
        chain = build_chain(spec)
        if spec.commands_csv:
            log = RingRowLog(Path(spec.commands_csv), ("t_s", "frame", *chain.outputs),
                             spec.rate_hz, spec.commands_buffer_s, integer_columns=("frame",))
        last_seq = 0
        last_ctl_seq = -1
        # Optional: a chain that switches textures or takes b live (DriveChain does).
        apply_control = getattr(chain, "apply_control", None)
        live_stats = getattr(chain, "live_stats", None)
        # The station that started us, as multiprocessing knows it: getppid() here would
        # already be init's pid if the station was killed while this process started.
        started_by = mp.parent_process()
        parent = started_by.pid if started_by is not None else os.getppid()
        timer.start()
        if ready_event is not None:
            ready_event.set()  # the chain is built: the station may start its sources
        # A read never holds up the tick: a writer stuck mid-write (killed there) gives
        # the last consistent values after a quarter tick, and the loop still sees a stop.
        read_timeout_s = 0.25 / spec.rate_hz
        while not stop_event.is_set():
            tick_time = timer.wait()
            seq, v = state.read(read_timeout_s)
            ctl_seq, ctl = control.read(read_timeout_s)
            if ctl_seq and ctl_seq != last_ctl_seq:  # only when the station wrote anew
                last_ctl_seq = ctl_seq
                if apply_control is not None:
                    apply_control(ctl[4], ctl[5])
            t0 = ctl[3]  # the station's epoch: t_s = 0 at its first frame
            gain = ctl[0] if ctl[2] > 0.5 and not ctl[6] > 0.5 else 0.0
            if seq and ctl_seq:
                out = chain.tick(tick_time - t0, v[1] > 0.5, v[2], v[3], v[5], v[6], gain,
                                 ctl[1])
                if seq != last_seq:
                    # The first command that uses this frame: the frame-to-command latency.
                    latency.add(time.perf_counter() - v[7])
                    last_seq = seq
                if log is not None:
                    log.write(tick_time - t0, v[8], *out)
            if timer.stats_due():
                if os.getppid() != parent:
                    # The station died without stopping us (SIGKILL): stop safely, now.
                    raise RuntimeError("the station process is gone")
                if log is not None and log.error is not None:
                    raise RuntimeError(f"commands log {spec.commands_csv}: {log.error}")
                # Once a second: the live figures for the status line and the web view.
                live = {"render": timer.stats().as_dict(),
                        "frame_to_command_ms": latency.percentiles_ms()}
                if live_stats is not None:
                    live["texture"] = live_stats()
                results.put(("live", live))
    except BaseException as exc:
        results.put(("fault", f"render loop: {exc!r}\n{traceback.format_exc()}"))
    finally:
        # Every step runs whatever the one before did, and the stats always go out: the
        # station waits for them.
        faults: list[str] = []
        if chain is not None:
            try:
                chain.safe_stop()
            except BaseException as exc:
                faults.append(f"safe stop: {exc!r}")
            faults += list(getattr(chain, "faults", ()))
        if log is not None:
            try:
                log.close()
            except BaseException as exc:
                faults.append(f"commands log {exc}")
        for fault in faults:
            results.put(("fault", f"render process: {fault}"))
        stats = timer.stats().as_dict()
        stats["scheduling"] = scheduling
        stale = state.stale_reads + control.stale_reads
        if stale:
            stats["stale_reads"] = stale
        if log is not None:
            stats["commands_log"] = log.stats()
        if chain is not None and hasattr(chain, "stats"):
            try:
                stats["chain"] = chain.stats()
            except BaseException as exc:
                stats["chain"] = {"error": repr(exc)}
        results.put(("stats", {"render": stats,
                               "frame_to_command_ms": latency.percentiles_ms()}))
