"""The board stops by itself when the render process dies: the real render process
drives the emulated QB board over a pseudo-terminal, is killed (SIGKILL: no safe stop
runs), and the board's watchdog puts the motors at rest within its 20 ms period after
the last frame it got, by the board's own clock."""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import queue
import signal
import time

from fydpad.config import StationConfig
from fydpad.motors import qb_protocol as qp
from fydpad.motors.qb import QbBoardConfig
from fydpad.motors.qb_emulator import QbEmulator
from fydpad.station.render import CONTROL_FIELDS, RenderSpec, render_main
from fydpad.station.shared import SharedFingerState, SharedRecord
from fydpad.station.station import StationOptions
from vision.state import FingerState

#: A hang guard for the render process's start (spawn, imports, the chain, the board's
#: set-up): several times the station's own wait, as this machine may be far more loaded
#: than a station's (a test run beside others and a CPU hog).
START_TIMEOUT_S = 5 * StationOptions().render_start_timeout_s


def _said(results) -> object:
    """What the render process reported (its fault), or that it said nothing."""
    try:
        return results.get_nowait()
    except queue.Empty:
        return "the render process reported nothing"


def _wait(cond, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.005)
    return cond()


def test_killed_render_process_leaves_the_board_at_rest_within_the_watchdog_period():
    with QbEmulator(device_id=1) as emu:
        # Replies the emulator (a thread here, on a loaded machine) is late with are
        # reused, however many: this test is about the board's watchdog, not the host's.
        # Its set-up replies may be as late: a generous set-up deadline (a hang guard).
        cfg = StationConfig(qb=QbBoardConfig(port=emu.port, device_id=1, timeout_s=10.0,
                                             max_missed_replies=1_000_000))
        assert cfg.qb.watchdog_cs == 2  # the default: nothing armed by the test
        spec = RenderSpec(motors="qb", config=cfg, realtime=False)
        ctx = mp.get_context("spawn")
        state = SharedFingerState()
        state.publish(FingerState(t_s=0.0, contact=True, x_mm=0.0, y_mm=0.0,
                                  indentation_mm=2.0, force_n=1.0), 0.0, 1)
        control = SharedRecord(CONTROL_FIELDS)
        control.write([1.0, math.nan, 1.0, time.perf_counter(), 0.0, math.nan, 0.0])
        stop, ready, results = ctx.Event(), ctx.Event(), ctx.Queue()
        p = ctx.Process(target=render_main,
                        args=(spec, state, control, stop, results, ready), daemon=True)
        p.start()
        try:
            assert ready.wait(START_TIMEOUT_S), _said(results)
            # The loop drives the board: duties go out tick after tick.
            n0 = emu.received.count(qp.CMD_SET_INPUTS)
            assert _wait(lambda: emu.received.count(qp.CMD_SET_INPUTS) > n0 + 200, 60), (
                "the render loop did not drive the board", _said(results))
            assert emu.watchdog == 1  # armed at activation: 2 cs
            os.kill(p.pid, signal.SIGKILL)
            p.join(30)
            assert p.exitcode == -signal.SIGKILL
            # No safe stop ran (the process was killed): the board stops by itself.
            assert _wait(emu.at_rest, 10)
            stops = emu.watchdog_stops
            assert stops and stops[-1][1] <= emu.last_frame_s + 0.02 + 1e-9
            assert all(stop - last == 0.02 or abs(stop - last - 0.02) < 1e-9
                       for last, stop in stops)
            assert qp.CMD_ACTIVATE not in emu.received[-1:]  # no deactivation was sent
            assert emu.activation == 0 and not emu.plant.powered
        finally:
            if p.is_alive():
                p.kill()
